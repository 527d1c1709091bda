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

Arithmetic-coded JPEGs (which can code a flat block in a small fraction of a bit) and the other formats have
no byte bound; the memory bound holds for all.
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import BinaryIO

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
    return None


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
