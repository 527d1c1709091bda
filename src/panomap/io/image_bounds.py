"""What an image file's header claims, held to what its bytes can hold and to the memory there is.

A decoder fills what a file lacks (libjpeg with grey, after a warning): a JPEG of 629 bytes whose header
claims 16000 x 16000 px decoded to 256 megapixels of grey in 6 s and 2 GB. Two bounds refuse such a file
from its header, before its pixels take memory:

- the fewest bytes its format can code an image of that size in (:func:`least_file_bytes`): a Huffman-coded
  JPEG spends at least one bit on each 8 x 8 block of its full-resolution component (the DC difference's
  code, one bit at the least); a PNG's pixel rows (a filter byte and the packed samples each) come out of
  deflate at most 1032 times smaller (a 258-byte match in two bits). Both bounds are far below any real
  picture's file (a flat grey 16000 x 16000 baseline JPEG takes 3 MB, the bound 500 kB);
- the memory its pixels take decoded (:func:`decoded_bytes`), against the memory available
  (:func:`available_memory`).

A TIFF's strips (or tiles) are where its first directory says (:func:`tiff_data_end`: a file cut short ends
before them); uncompressed they hold every byte of the pixels, PackBits codes 128 bytes in 2 at best, deflate
as in a PNG, LZW a string of at most 4096 bytes in a code of at least 9 bits. A WebP's decoder refuses data that
end early itself. Arithmetic-coded JPEGs (which can code a flat block in a small fraction of a bit), lossless
WebP (a flat 7000 x 7000 picture in 1.9 kB), TIFF's other codings and the other formats have no byte bound; the
memory bound holds for all.
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import BinaryIO, Literal

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
JPEG_SIGNATURE = b"\xff\xd8\xff"
# Deflate's largest ratio: a 258-byte match coded in two bits (a one-bit length code, a one-bit distance code).
DEFLATE_MAX_RATIO = 1032
# The samples of a pixel of each PNG colour type (grey, RGB, palette, grey + alpha, RGBA).
PNG_SAMPLES = {0: 1, 2: 3, 3: 1, 4: 2, 6: 4}
# The channels OpenCV decodes a PNG of each colour type to (a palette to BGR, grey + alpha to BGRA).
PNG_DECODED_CHANNELS = {0: 1, 2: 3, 3: 3, 4: 4, 6: 4}
# The start-of-frame markers of Huffman-coded JPEGs: baseline, extended, progressive and lossless.
JPEG_HUFFMAN_FRAMES = frozenset({0xC0, 0xC1, 0xC2, 0xC3})
# Every start-of-frame marker (C4 is a Huffman table, C8 reserved, CC an arithmetic conditioning table).
JPEG_FRAMES = frozenset(range(0xC0, 0xD0)) - {0xC4, 0xC8, 0xCC}
# The most a TIFF's coding shrinks its pixels' bytes, by its Compression tag: none, LZW, deflate (Adobe's and
# the old code), PackBits.
TIFF_MAX_RATIO = {1: 1, 5: 4096 * 8 // 9, 8: DEFLATE_MAX_RATIO, 32946: DEFLATE_MAX_RATIO, 32773: 64}
# TIFF's field types' sizes (bytes): SHORT, LONG and LONG8 (BigTIFF) are the ones offsets and counts take.
TIFF_TYPE_BYTES = {3: 2, 4: 4, 16: 8}
# The most entries read from a TIFF directory, and the most offsets from one field.
MAX_TIFF_ENTRIES = 4096
MAX_TIFF_VALUES = 1 << 20
# The most segments read before the frame header (a file's APPn segments: EXIF, ICC, XMP...).
MAX_JPEG_SEGMENTS = 256


def least_file_bytes(path: str | Path, size: tuple[int, int]) -> tuple[str, int] | None:
    """(format, bytes): the fewest bytes a file of ``path``'s format can hold an image of ``size`` (width,
    height; px) in, its header's claim; None where there is no such bound (another format, an arithmetic-coded
    or hierarchical JPEG, a header not understood)."""
    width, height = size
    with Path(path).open("rb") as handle:
        head = handle.read(33)
        if head.startswith(PNG_SIGNATURE) and head[12:16] == b"IHDR":
            depth, colour = head[24], head[25]
            samples = PNG_SAMPLES.get(colour)
            if samples is None or depth not in (1, 2, 4, 8, 16):
                return None
            row = 1 + (width * samples * depth + 7) // 8
            return "PNG", row * height // DEFLATE_MAX_RATIO
        if head.startswith(JPEG_SIGNATURE):
            handle.seek(2)
            frame = _jpeg_frame_marker(handle)
            if frame not in JPEG_HUFFMAN_FRAMES:
                return None
            return "JPEG", math.ceil(width / 8) * math.ceil(height / 8) // 8
        if head[:4] in (b"II*\x00", b"MM\x00*"):
            fields = _tiff_fields(handle, head, {259, 258, 277})
            ratio = TIFF_MAX_RATIO.get(fields.get(259, [1])[0]) if fields is not None else None
            if fields is None or ratio is None:
                return None
            bits = sum(fields.get(258, [1])) if 258 in fields else fields.get(277, [1])[0]
            return "TIFF", (width * bits + 7) // 8 * height // ratio
    return None


def tiff_data_end(path: str | Path) -> int | None:
    """The byte past a TIFF's last strip or tile, as its first directory places them (None for another format,
    or a directory that does not parse): a file shorter than that was cut short."""
    with Path(path).open("rb") as handle:
        head = handle.read(16)
        fields = _tiff_fields(handle, head, {273, 279, 324, 325}) if head[:4] in (b"II*\x00", b"MM\x00*") else None
    if fields is None:
        return None
    offsets, counts = fields.get(273, fields.get(324)), fields.get(279, fields.get(325))
    if not offsets or counts is None or len(counts) != len(offsets):
        return None
    return max(offset + count for offset, count in zip(offsets, counts, strict=True))


def _tiff_fields(handle: BinaryIO, head: bytes, tags: set[int]) -> dict[int, list[int]] | None:
    """The values of ``tags`` (those present, each a list) in the first directory of the classic TIFF open in
    ``handle`` (``head``: its first 8 bytes or more); None where it is a BigTIFF or does not parse."""
    order: Literal["little", "big"] = "little" if head[:2] == b"II" else "big"
    handle.seek(int.from_bytes(head[4:8], order))
    count = int.from_bytes(handle.read(2), order)
    entries = handle.read(12 * count)
    if count > MAX_TIFF_ENTRIES or len(entries) != 12 * count:
        return None
    fields: dict[int, list[int]] = {}
    for start in range(0, len(entries), 12):
        tag = int.from_bytes(entries[start : start + 2], order)
        kind = int.from_bytes(entries[start + 2 : start + 4], order)
        number = int.from_bytes(entries[start + 4 : start + 8], order)
        size = TIFF_TYPE_BYTES.get(kind)
        if tag not in tags or size is None or size == 8:
            continue
        if not 0 < number <= MAX_TIFF_VALUES:
            return None
        data = entries[start + 8 : start + 8 + size * number]
        if size * number > 4:
            handle.seek(int.from_bytes(entries[start + 8 : start + 12], order))
            data = handle.read(size * number)
            if len(data) != size * number:
                return None
        fields[tag] = [int.from_bytes(data[k : k + size], order) for k in range(0, size * number, size)]
    return fields


def _jpeg_frame_marker(handle: BinaryIO) -> int | None:
    """The start-of-frame marker's second byte (0xC0...) of the JPEG open in ``handle`` (at the byte after its
    start-of-image marker), or None where a scan or the end comes first or the segments do not parse."""
    for _ in range(MAX_JPEG_SEGMENTS):
        if handle.read(1) != b"\xff":
            return None
        byte = handle.read(1)
        while byte == b"\xff":  # (fill bytes before a marker)
            byte = handle.read(1)
        if len(byte) != 1 or byte[0] in (0x00, 0xD9, 0xDA):
            return None
        if byte[0] in JPEG_FRAMES:
            return byte[0]
        if 0xD0 <= byte[0] <= 0xD7 or byte[0] == 0x01:
            continue  # (a marker without a length)
        length = handle.read(2)
        if len(length) != 2 or int.from_bytes(length, "big") < 2:
            return None
        handle.seek(int.from_bytes(length, "big") - 2, os.SEEK_CUR)
    return None


def decoded_bytes(path: str | Path, size: tuple[int, int], mode: str) -> int:
    """The bytes an image of ``size`` (width, height; px) takes decoded as OpenCV decodes it: its channels
    (a PNG's from its header; else from Pillow's ``mode``, a palette as three) times its samples' bytes."""
    from PIL import Image

    width, height = size
    with Path(path).open("rb") as handle:
        head = handle.read(33)
    if head.startswith(PNG_SIGNATURE) and head[12:16] == b"IHDR" and head[25] in PNG_DECODED_CHANNELS:
        return width * height * PNG_DECODED_CHANNELS[head[25]] * (2 if head[24] == 16 else 1)
    try:
        channels = {"P": 3, "PA": 4, "LA": 4}.get(mode) or Image.getmodebands(mode)
    except (KeyError, ValueError):
        channels = 4
    return width * height * channels * (2 if mode.startswith("I;16") else 1)


def available_memory() -> int | None:
    """The memory (bytes) this machine can give without swapping (Linux's MemAvailable, else its free pages),
    None where the system does not say."""
    try:
        with open("/proc/meminfo", encoding="ascii") as handle:
            for line in handle:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return int(os.sysconf("SC_AVPHYS_PAGES")) * int(os.sysconf("SC_PAGE_SIZE"))
    except (ValueError, OSError, AttributeError):
        return None
