"""Reading and writing images and maps, keeping depth and channels.

Images are NumPy arrays (H, W) or (H, W, C) with C in 1, 3, 4, uint8 or
uint16, channels in OpenCV's order (BGR[A]). Every write goes through a
temporary file and a rename.

A bad image gets one PanomapError and nothing else on stderr: OpenCV's own log
(``[ WARN ]``, ``[ERROR]`` lines) is silenced while it decodes, and a PNG is
checked whole (its chunks and their CRCs, by Pillow) before libpng sees it,
since libpng writes its complaint about a truncated file straight to stderr.
"""

from __future__ import annotations

import os
import re
import threading
import warnings
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import cv2
import numpy as np
from numpy.typing import NDArray

from .. import inputs
from ..errors import PanomapError, printable
from ..files import file_path, input_file, write_bytes_atomic, write_with
from .image_bounds import available_memory, decoded_bytes, least_file_bytes, tiff_data_end
from .stderr_kept import stderr_kept

if TYPE_CHECKING:
    from ..rig import CameraRig

SIXTEEN_BIT_SUFFIXES = {".png", ".tif", ".tiff", ".pgm", ".ppm", ".pnm"}
ALPHA_SUFFIXES = {".png", ".tif", ".tiff", ".webp"}
# The largest image read (width x height): 16384 x 16384, 768 MB as 8-bit BGR. A larger one
# is refused from its header, before its pixels take memory.
MAX_IMAGE_PIXELS = 16384 * 16384
_PILLOW_LOCK = threading.Lock()  # header_size changes Pillow's process-wide limit for a moment
_OPENCV_LOG_LOCK = threading.Lock()  # OpenCV's log level is process-wide
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
JPEG_SIGNATURE = b"\xff\xd8\xff"
TIFF_SIGNATURES = (b"II*\x00", b"MM\x00*", b"II+\x00", b"MM\x00+")  # (classic and BigTIFF)
# The still-image formats whose header Pillow reads, by its names for them, as said: a file of one that OpenCV
# cannot decode is corrupt, not a video (FFmpeg decodes a corrupt WebP or TIFF as a frame, filling what it lacks).
STILL_FORMATS = {"PNG": "PNG", "JPEG": "JPEG", "TIFF": "TIFF", "WEBP": "WebP", "BMP": "BMP", "PPM": "PNM"}
# The problem of a file no decoder here recognises: the one a caller may try as a video instead.
UNKNOWN_FORMAT = "cannot read it as an image (unknown format or corrupt)"


def read_image(
    path: str | Path, expected_size: tuple[int, int] | None = None, expected_by: str = "the table"
) -> NDArray[Any]:
    """Read an image unchanged (depth, channels).

    The size is read from the file's header before anything is decoded: an
    image beyond :data:`MAX_IMAGE_PIXELS`, or not of ``expected_size``
    (width, height) when one is given, is refused without decoding it.

    Parameters
    ----------
    path : str or path
        The image file (PNG, JPEG, TIFF, ... as OpenCV reads them).
    expected_size : (width, height), optional
        The size the image must have (px), e.g. the one a table was made for.
    expected_by : str
        What expects that size, named in the error.

    Returns
    -------
    (H, W[, C]) ndarray
        The pixels, uint8 or uint16, BGR (or BGRA) where in colour.

    Raises
    ------
    PanomapError
        Naming the file when it is missing, unreadable, too large, not of
        ``expected_size`` ("the image is W x H, {expected_by} is for ..."), or
        of an unsupported depth.
    """
    path = input_file(path, missing="no such image file")
    with path.open("rb") as handle:
        kind = float_format(handle.read(16))
    if kind is not None:  # (refused before decoding: a large one would take its memory first)
        raise PanomapError(f"images must be 8- or 16-bit, this one is {kind} (32-bit float)", path)
    declared = _header(path)
    if declared is not None:
        check_image_size(path, declared[0], inputs.optional_image_size(expected_size, "expected_size"), expected_by)
        _check_claim(path, declared[0], declared[1])
    data = np.fromfile(path, dtype=np.uint8)
    if data[: len(PNG_SIGNATURE)].tobytes() == PNG_SIGNATURE:
        problem = png_problem(path)
        if problem is not None:
            raise PanomapError(f"cannot read it as an image (a truncated or corrupt PNG: {problem})", path)
    if data[: len(JPEG_SIGNATURE)].tobytes() == JPEG_SIGNATURE:
        problem = jpeg_problem(data.tobytes())
        if problem is not None:
            raise PanomapError(f"cannot read it as an image (a truncated or corrupt JPEG: {problem})", path)
    tiff = data[:4].tobytes() in TIFF_SIGNATURES
    image, said = _decode(data, tiff) if data.size else (None, [])
    failed = [line for line in said if "TIFF_Error" in line] if tiff else []
    if failed:  # (libtiff fills what a strip's data lack, as libjpeg does, and says so in OpenCV's log alone)
        raise PanomapError(f"cannot read it as an image (a truncated or corrupt TIFF: {_said(failed[0])})", path)
    short = [line for line in said if _DATA_ENDS.search(line)]
    if short and image is not None:  # (the decoder filled what the file lacks)
        raise PanomapError(f"cannot read it as an image (a truncated or corrupt file: {_said(short[0])})", path)
    if image is None and declared is not None and declared[2] in STILL_FORMATS:  # (no video: FFmpeg would fill it)
        reason = f": {_said(said[0])}" if said else ""
        raise PanomapError(
            f"cannot read it as an image (a truncated or corrupt {STILL_FORMATS[declared[2]]}{reason})", path
        )
    if image is None:
        raise PanomapError(UNKNOWN_FORMAT + (f": {_said(said[0])}" if said else ""), path)
    if image.dtype not in (np.uint8, np.uint16):
        raise PanomapError(f"images must be 8- or 16-bit, this one is {image.dtype}", path)
    check_image_size(path, (int(image.shape[1]), int(image.shape[0])), expected_size, expected_by)
    return image


# The float image formats OpenCV reads and Pillow does not, by their files' first bytes.
FLOAT_SIGNATURES = {
    b"#?RADIANCE": "a Radiance HDR image",
    b"#?RGBE": "a Radiance HDR image",
    b"\x76\x2f\x31\x01": "an OpenEXR image",
    b"PF\n": "a PFM image",
    b"Pf\n": "a PFM image",
}


def read_rig_pictures(
    rig: CameraRig,
    paths: Sequence[Path],
    read: Callable[[Path, tuple[int, int] | None, str], NDArray[Any]] | None = None,
) -> list[Any]:
    """A rig's pictures from image files, as :class:`panomap.rig.RigRemapper` takes them: the one frame holding
    every camera's picture (a rig with ``offsets``), or one picture per camera in the rig's order; each checked
    against its size (the view commands given a rig, ``rig learn``, ``panomap batch``). ``read`` reads a file
    as :func:`read_image` does (path, expected size, what expects it; by default, :func:`read_image`).

    Raises PanomapError for a wrong number of files (naming what the rig takes, with no file) and, as
    :func:`read_image`, for a file that cannot be read or is not of its camera's size."""
    if rig.offsets is not None:
        if len(paths) != 1:
            raise PanomapError(f"the rig's cameras share one frame: give that one picture, not {len(paths)}")
        return [(read or read_image)(paths[0], rig.frame_size, "the rig's frame")]
    if len(paths) != rig.count:
        names = ", ".join(rig.names)
        raise PanomapError(f"give one picture per camera of the rig, in its order ({names}), not {len(paths)}")
    pictures = [(read or read_image)(path, table.image_size, f"camera {name}") for path, table, name in
                zip(paths, rig.tables, rig.names, strict=True)]  # fmt: skip
    check_same_depth(paths, pictures)
    return pictures


def check_same_depth(paths: Sequence[str | Path], pictures: Sequence[NDArray[Any]]) -> None:
    """Refuse, naming the file, a rig's picture whose pixels are not of the first one's type (8 or 16 bits): the
    blend brings grey and colour alike (:func:`panomap.rig.blend.alike_pictures`), not depths."""
    for path, picture in zip(paths[1:], pictures[1:], strict=True):
        if picture.dtype != pictures[0].dtype:
            raise PanomapError(
                f"its pixels are {picture.dtype.name}, those of {printable(str(paths[0]))} {pictures[0].dtype.name}: "
                "give the rig's pictures alike",
                path,
            )


def float_format(head: bytes) -> str | None:
    """Which float image format a file's first bytes ``head`` (16 are enough) begin, or None."""
    return next((kind for signature, kind in FLOAT_SIGNATURES.items() if head.startswith(signature)), None)


def _decode(data: NDArray[np.uint8], tiff: bool = False) -> tuple[NDArray[Any] | None, list[str]]:
    """``cv2.imdecode``, with OpenCV's log silenced and what its decoders (libjpeg, libpng) write to stderr
    themselves kept: the image (None for what it cannot decode, or refuses as too large) and those lines. For a
    ``tiff``, OpenCV's errors are kept too (libtiff's complaints reach its log alone)."""
    logging = cv2.utils.logging
    with _OPENCV_LOG_LOCK:
        level = logging.getLogLevel()
        logging.setLogLevel(logging.LOG_LEVEL_ERROR if tiff else logging.LOG_LEVEL_SILENT)
        try:
            with stderr_kept() as said:
                image = cv2.imdecode(data, cv2.IMREAD_UNCHANGED)
        except cv2.error:
            image = None
        finally:
            logging.setLogLevel(level)
    return image, [line.strip() for line in said if line.strip()]


# What libjpeg and libpng say where a file's data ends before its pixels do (they fill the rest in).
_DATA_ENDS = re.compile(r"premature end|not enough image data|read error|truncated", re.IGNORECASE)


def _said(line: str) -> str:
    """A decoder's line as a reason: its library's prefix off, at most 80 characters, printable."""
    text = re.sub(r"^(libpng (error|warning)|Corrupt JPEG data|\[ERROR:[^]]*\] global \S+ TIFF_Error):?\s*", "", line)
    text = text.replace(": : ", ": ").rstrip(".")
    return printable(text[:80])


def png_problem(path: str | Path) -> str | None:
    """What is wrong with a PNG file's structure (a missing end, a bad CRC), or None if it is whole.

    Pillow walks the chunks and checks their CRCs without decoding the pixels.
    """
    from PIL import Image

    with _PILLOW_LOCK, warnings.catch_warnings():
        warnings.simplefilter("ignore")  # (a bomb warning: the size was checked by the caller)
        limit, Image.MAX_IMAGE_PIXELS = Image.MAX_IMAGE_PIXELS, None
        try:
            with Image.open(path) as image:
                image.verify()
        except Exception as exc:  # Pillow raises OSError, SyntaxError, struct.error, ...: all say "corrupt"
            return " ".join(str(exc).split()) or exc.__class__.__name__
        finally:
            Image.MAX_IMAGE_PIXELS = limit
    return None


def jpeg_problem(data: bytes) -> str | None:
    """What is wrong with a JPEG file's structure (``data``: its bytes), or None if it looks whole.

    A decoder fills what a truncated file lacks with grey (OpenCV 5.0 and libjpeg warn and go on),
    so the structure is checked first: the last scan (after the last start-of-scan marker FF DA)
    must be closed by the end-of-image marker FF D9. Inside a scan's data an FF byte is always
    followed by 00 or a restart marker, so neither marker appears there by chance.
    """
    scan = data.rfind(b"\xff\xda")
    if scan < 0:
        return "no image data: the file ends before its first scan"
    if data.find(b"\xff\xd9", scan + 2) < 0:
        return "the file ends inside its image data, before the end-of-image marker"
    return None


def header_size(path: str | Path) -> tuple[int, int] | None:
    """(width, height) from an image file's header, without decoding it; None if Pillow cannot tell.

    Pillow (which matplotlib requires) reads the headers of PNG, JPEG, TIFF,
    WebP, BMP and PNM lazily; the formats only OpenCV reads are checked after
    decoding instead.
    """
    header = _header(path)
    return None if header is None else header[0]


def _header(path: str | Path) -> tuple[tuple[int, int], str, str] | None:
    """((width, height), Pillow's mode, Pillow's format) from an image file's header, as :func:`header_size` reads
    it."""
    from PIL import Image, UnidentifiedImageError

    if not Path(path).is_file():  # (a FIFO would block Pillow's read)
        return None
    with _PILLOW_LOCK, warnings.catch_warnings():
        # Pillow's own bomb check would refuse a large header before telling its size: the
        # limit here is MAX_IMAGE_PIXELS, checked by the caller; its other warnings (a TIFF's "Corrupt EXIF
        # data") are the decoder's to judge, not lines of their own.
        warnings.simplefilter("ignore")
        limit, Image.MAX_IMAGE_PIXELS = Image.MAX_IMAGE_PIXELS, None
        try:
            with Image.open(path) as image:
                (width, height), mode, kind = image.size, str(image.mode), str(image.format)
        except (UnidentifiedImageError, OSError, ValueError, SyntaxError):
            return None
        finally:
            Image.MAX_IMAGE_PIXELS = limit
    return (int(width), int(height)), mode, kind


def _check_claim(path: Path, size: tuple[int, int], mode: str) -> None:
    """Refuse, before decoding, an image whose header claims more pixels than its file's bytes can hold, or
    than the memory available holds decoded (:mod:`panomap.io.image_bounds`)."""
    width, height = size
    held = path.stat().st_size
    least = least_file_bytes(path, size)
    if least is not None and held < least[1]:
        raise PanomapError(
            f"cannot read it as an image (a truncated or corrupt {least[0]}: its header claims {width} x {height} px, "
            f"which take at least {_amount(least[1])}, not {_amount(held)})",
            path,
        )
    end = tiff_data_end(path)
    if end is not None and held < end:
        raise PanomapError(
            f"cannot read it as an image (a truncated TIFF: its pixels' data run to byte {end}, the file ends at "
            f"{held})",
            path,
        )
    needed, free = decoded_bytes(path, size, mode), available_memory()
    if free is not None and needed > free:
        raise PanomapError(
            f"the image is {width} x {height}: decoded, it takes {_amount(needed)} of memory, more than the "
            f"{_amount(free)} available",
            path,
        )


def _amount(size: int) -> str:
    """``size`` bytes as kB, MB or GB."""
    if size < 10_000:
        return f"{size} bytes"
    return f"{size / 1e9:.1f} GB" if size >= 1e9 else f"{size / 1e6:.1f} MB" if size >= 1e6 else f"{size / 1e3:.0f} kB"


# What an EXIF orientation other than 1 asks a viewer to do before showing the image.
EXIF_ORIENTATIONS = {
    2: "mirrored left to right",
    3: "turned 180 deg",
    4: "mirrored top to bottom",
    5: "mirrored and turned",
    6: "turned 90 deg clockwise",
    7: "mirrored and turned",
    8: "turned 90 deg counter-clockwise",
}


def orientation_note(path: str | Path) -> str | None:
    """A warning where the image file's EXIF orientation asks viewers to turn or mirror it; None otherwise.

    panomap takes the pixels as stored (a table belongs to the sensor's pixel grid, whatever a
    viewer shows); landmarks measured in a viewer that turned the image would not match them.
    """
    from PIL import Image, UnidentifiedImageError

    if not Path(path).is_file():  # (a FIFO would block Pillow's read)
        return None
    with _PILLOW_LOCK, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        limit, Image.MAX_IMAGE_PIXELS = Image.MAX_IMAGE_PIXELS, None
        try:
            with Image.open(path) as image:
                orientation = image.getexif().get(0x0112)
        except (UnidentifiedImageError, OSError, ValueError, SyntaxError):
            return None
        finally:
            Image.MAX_IMAGE_PIXELS = limit
    if orientation not in EXIF_ORIENTATIONS:
        return None
    return (
        f"its EXIF orientation ({orientation}) asks viewers to show it {EXIF_ORIENTATIONS[orientation]}: "
        "panomap takes the pixels as stored, so measure landmarks in the image as stored, not as a viewer shows it"
    )


def image_size(path: str | Path) -> tuple[int, int]:
    """(width, height) of an image file, from its header where Pillow reads it."""
    size = header_size(path)
    if size is not None:
        return size
    image = read_image(path)
    return int(image.shape[1]), int(image.shape[0])


def check_image_size(
    path: Path, size: tuple[int, int], expected_size: tuple[int, int] | None, expected_by: str
) -> None:
    """Refuse, naming ``path``, an image of ``size`` (W, H) other than ``expected_size`` (where given; ``expected_by``
    names what expects it) or beyond :data:`MAX_IMAGE_PIXELS`."""
    width, height = size
    if expected_size is not None and (width, height) != tuple(expected_size):
        raise PanomapError(
            f"the image is {width} x {height}, {expected_by} is for {expected_size[0]} x {expected_size[1]} images",
            path,
        )
    if width * height > MAX_IMAGE_PIXELS:
        raise PanomapError(
            f"the image is {width} x {height}: more than the {MAX_IMAGE_PIXELS // 1_000_000} megapixels panomap reads",
            path,
        )


def write_image(path: str | Path, image: NDArray[Any]) -> None:
    """Write an image, choosing the format by suffix; refuses to lose depth or alpha.

    The file is written whole or not at all (a temporary file renamed into place).

    Parameters
    ----------
    path : str or path
        The file to write; its suffix chooses the format (``.png``, ``.jpg``, ``.tif``, ...).
    image : (H, W[, C]) ndarray
        uint8 or uint16 pixels, BGR (or BGRA) where in colour.

    Raises
    ------
    TypeError
        ``image`` is no NumPy array.
    PanomapError
        An image of another dtype or shape (:func:`panomap.inputs.image`), a format that cannot hold
        its depth or alpha, or a file that cannot be written.
    """
    image = inputs.image(image)
    path = file_path(path)
    suffix = path.suffix.lower()
    if image.dtype == np.uint16 and suffix not in SIXTEEN_BIT_SUFFIXES:
        raise PanomapError("16-bit images need PNG, TIFF or PNM output, not " + (suffix or "no suffix"), path)
    if image.ndim == 3 and image.shape[2] == 4 and suffix not in ALPHA_SUFFIXES:
        raise PanomapError("images with alpha need PNG, TIFF or WebP output, not " + (suffix or "no suffix"), path)
    check_image_output(path, (int(image.shape[1]), int(image.shape[0])))
    logging = cv2.utils.logging
    with _OPENCV_LOG_LOCK:  # (OpenCV logs an encoder's failure as [ERROR] lines of its own)
        level = logging.getLogLevel()
        logging.setLogLevel(logging.LOG_LEVEL_SILENT)
        try:
            ok, encoded = cv2.imencode(suffix, image)
        except cv2.error:
            ok = False
        finally:
            logging.setLogLevel(level)
    if not ok:
        raise PanomapError(f"cannot write an image in the format {suffix}", path)
    write_bytes_atomic(path, encoded.tobytes())


# The largest side (px) of an image each format holds, where it is less than any view's (32000 px).
MAX_FORMAT_SIDE = {".webp": 16383}


def check_image_output(path: str | Path, size: tuple[int, int]) -> None:
    """Refuse, before any work, an output image named ``path`` that no writer here writes (an unknown suffix, or
    none), or of ``size`` (width, height; px) more than its format holds (WebP: 16383 px a side)."""
    suffix = Path(path).suffix.lower()
    if not suffix or not cv2.haveImageWriter(f"x{suffix}"):
        raise PanomapError(f"cannot write an image in the format {suffix or '(no suffix)'}: name it .png or .jpg", path)
    most = MAX_FORMAT_SIDE.get(suffix)
    if most is not None and max(size) > most:
        raise PanomapError(
            f"an image of {size[0]} x {size[1]} px: {suffix[1:].upper()} holds at most {most} px a side (write .png)",
            path,
        )


def save_map(path: str | Path, map_uv: NDArray[np.float32]) -> None:
    """Save a map (H, W, 2) float32 as ``.npy`` (the conventions' map file)."""
    array = np.ascontiguousarray(map_uv, dtype=np.float32)
    write_with(path, lambda handle: np.save(handle, array, allow_pickle=False))


def image_file_bytes(size: tuple[int, int], like: NDArray[Any]) -> int:
    """The most bytes an image of ``size`` (W, H) px, of the channels and depth of ``like``, takes written:
    its pixels uncompressed, with a PNG's filter byte a row and headers (a compressed file is smaller): for
    :func:`panomap.files.check_room`."""
    width, height = size
    channels = like.shape[2] if like.ndim == 3 else 1
    return width * height * channels * like.dtype.itemsize + height + IMAGE_HEADER_BYTES


# Room for an image file's headers and metadata, beyond its pixels.
IMAGE_HEADER_BYTES = 4096

PGM_NO_SOURCE = 65535


def map_file_bytes(
    size: tuple[int, int], npy: Path | None, pgm: tuple[Path | None, Path | None] = (None, None)
) -> list[tuple[Path, int]]:
    """The bytes a map of ``size`` (W, H) takes at least, as ``.npy`` at ``npy`` (float32 u and v: 8 a pixel)
    and as the two 16-bit PGM planes at ``pgm`` (2 a pixel each), where given: for
    :func:`panomap.files.check_room`."""
    width, height = size
    files = [(npy, width * height * 8)] + [(path, width * height * 2) for path in pgm]
    return [(path, size) for path, size in files if path is not None]


def map_to_pgm(map_uv: NDArray[np.float32]) -> tuple[NDArray[np.uint16], NDArray[np.uint16]]:
    """A map as the two 16-bit planes of integer source columns and rows that ffmpeg's ``remap`` takes.

    Parameters
    ----------
    map_uv : (H, W, 2) float32 ndarray
        Source (u, v) per output pixel, NaN where there is no source.

    Returns
    -------
    xmap, ymap : (H, W) uint16 ndarrays
        ``rint(u)`` and ``rint(v)`` (half to even, as ``cv2.remap``'s nearest
        neighbour rounds), 65535 (outside any frame, so ffmpeg fills it) where
        there is no source or the position rounds below 0.

    Raises
    ------
    PanomapError
        If a source position is beyond 65534, which 16-bit maps cannot hold.
    """
    array = np.asarray(map_uv, dtype=np.float32)
    if array.ndim != 3 or array.shape[2] != 2:
        raise PanomapError(f"a map must have shape (H, W, 2), not {array.shape}")
    with np.errstate(invalid="ignore"):
        rounded = np.rint(array)
        valid = np.all(np.isfinite(rounded), axis=2) & np.all(rounded >= 0, axis=2)
        if np.any(valid & np.any(rounded >= PGM_NO_SOURCE, axis=2)):
            raise PanomapError("the map reaches beyond pixel 65534, more than 16-bit PGM maps hold")
    planes = np.where(valid[..., None], rounded, PGM_NO_SOURCE).astype(np.uint16)
    return np.ascontiguousarray(planes[..., 0]), np.ascontiguousarray(planes[..., 1])


def pgm_map_paths(prefix: str | Path) -> tuple[Path, Path]:
    """``PREFIX_x.pgm`` and ``PREFIX_y.pgm``: where :func:`save_map_pgm` writes.

    A ``prefix`` that names a folder (it ends with a path separator, or is an existing folder)
    gives ``FOLDER/map_x.pgm`` and ``FOLDER/map_y.pgm`` (``a/`` wrote ``./a_x.pgm``).
    """
    text = os.fspath(prefix)
    if text.endswith(("/", os.sep)) or Path(text).is_dir():
        return Path(text) / "map_x.pgm", Path(text) / "map_y.pgm"
    path = Path(text)
    return path.with_name(f"{path.name}_x.pgm"), path.with_name(f"{path.name}_y.pgm")


def save_map_pgm(prefix: str | Path, map_uv: NDArray[np.float32]) -> tuple[Path, Path]:
    """Save a map for ffmpeg's ``remap`` filter as ``PREFIX_x.pgm`` and ``PREFIX_y.pgm``.

    Binary 16-bit PGM (P5, maxval 65535, big-endian) of :func:`map_to_pgm`'s
    planes: nearest neighbour, integer source column and row per output pixel.
    Use them as ``ffmpeg -i IN -i PREFIX_x.pgm -i PREFIX_y.pgm -lavfi remap OUT``.
    Returns the two paths.
    """
    xmap, ymap = map_to_pgm(map_uv)
    paths = pgm_map_paths(prefix)
    for path, plane in zip(paths, (xmap, ymap), strict=True):
        write_image(path, plane)
    return paths


def encode_png(image: NDArray[Any], compression: int = 1) -> bytes:
    """PNG bytes of an image (8- or 16-bit, 1, 3 or 4 channels, BGR[A]), e.g. to serve it."""
    ok, encoded = cv2.imencode(".png", image, [cv2.IMWRITE_PNG_COMPRESSION, int(compression)])
    if not ok:
        raise PanomapError("cannot encode the image as PNG")
    return bytes(encoded.tobytes())
