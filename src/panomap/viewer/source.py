"""What the viewer shows: a still image, a video file, or a live stream or capture device.

A still image is decoded here (as every panomap command reads it) and sent to the page once, as a
lossless PNG, so that the page samples exactly the pixels ``panomap perspective`` samples. A video
file that a browser plays itself (H.264, VP8/9 or AV1 in MP4 or WebM) is sent as it is, with HTTP
range requests; the page falls back to frames decoded here (:mod:`panomap.viewer.feed`) where the
browser cannot play it. Everything else, and live sources, is decoded here and sent frame by frame.
"""

from __future__ import annotations

import dataclasses
import io
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import av
import numpy as np
from numpy.typing import NDArray

from ..errors import PanomapError
from ..io.images import UNKNOWN_FORMAT, encode_png, read_image
from ..video.handoff import reason
from ..video.source import is_live, open_input

# Codecs and pixel formats a browser plays by itself (in MP4, or WebM but for H.264).
BROWSER_CODECS = {"h264", "vp8", "vp9", "av1"}
BROWSER_PIXEL_FORMATS = {"yuv420p", "yuvj420p"}


@dataclass(frozen=True)
class Source:
    """The viewer's input.

    Attributes
    ----------
    name : str
        The path or URL as given.
    kind : str
        ``"image"``, ``"video"`` (a file: it has an end, can pause and seek) or ``"live"``.
    size : (width, height)
        Pixels of the image or of the video's frames.
    image_png : bytes or None
        A still image, as 8-bit PNG (grey and 16-bit images converted for display).
    mime : str or None
        A video file a browser can play itself: its MIME type (the page checks ``canPlayType``).
    duration_s, frame_rate : float or None
        A video's length (s) and frames per second, where its header says.
    """

    name: str
    kind: str
    size: tuple[int, int]
    image_png: bytes | None = None
    mime: str | None = None
    duration_s: float | None = None
    frame_rate: float | None = None
    # A live source's connection, opened to read what it is and kept for the first reading (some cameras take
    # one client at a time); None once taken, and for other sources.
    connection: Any = field(default=None, compare=False, repr=False)

    @property
    def path(self) -> Path | None:
        """The file of an image or video file on this machine; None for a live source or a URL."""
        return None if self.kind == "live" or is_live(self.name) else Path(self.name)


class HeldFile:
    """A source file opened once: what the viewer sends and decodes, whatever its name points to later (a link
    swapped, the file replaced or removed). Read at offsets (``os.pread``), so that any number of readers share
    it; :meth:`reader` gives each decoder its own position. Close it with :meth:`close`.

    Raises
    ------
    PanomapError
        Naming the file, when it cannot be opened.
    """

    def __init__(self, path: str | Path) -> None:
        self.name = str(path)
        try:
            self._file = open(path, "rb", buffering=0)  # (held until close)
        except OSError as exc:
            raise PanomapError(f"cannot open it ({exc.strerror or exc})", path) from None

    @property
    def size(self) -> int:
        """The file's size now (bytes)."""
        return os.fstat(self._file.fileno()).st_size

    def read_at(self, offset: int, count: int) -> bytes:
        """Up to ``count`` bytes from ``offset`` (fewer at the end of the file)."""
        return os.pread(self._file.fileno(), count, offset)

    def reader(self) -> io.RawIOBase:
        """A file object over the held file with its own position (for PyAV)."""
        return _HeldReader(self)

    def close(self) -> None:
        """Let the file go (readers fail after this)."""
        self._file.close()


class _HeldReader(io.RawIOBase):
    """Reads a :class:`HeldFile` from a position of its own."""

    def __init__(self, held: HeldFile) -> None:
        super().__init__()
        self._held = held
        self._position = 0

    def readable(self) -> bool:
        return True

    def seekable(self) -> bool:
        return True

    def readinto(self, buffer: Any) -> int:
        data = self._held.read_at(self._position, len(buffer))
        buffer[: len(data)] = data
        self._position += len(data)
        return len(data)

    def seek(self, offset: int, whence: int = io.SEEK_SET) -> int:
        base = {io.SEEK_SET: 0, io.SEEK_CUR: self._position, io.SEEK_END: self._held.size}[whence]
        self._position = max(0, base + offset)
        return self._position

    def tell(self) -> int:
        return self._position


def open_held(held: HeldFile) -> Any:
    """A PyAV container reading ``held`` (as :func:`~panomap.video.source.open_input` opens a name).

    Raises
    ------
    PanomapError
        Naming the file, when PyAV cannot open it or it holds no video.
    """
    try:
        container = av.open(held.reader())
    except (av.error.FFmpegError, OSError, ValueError) as exc:
        raise PanomapError(f"cannot open it as a video ({reason(exc)})", held.name) from None
    if not container.streams.video:
        container.close()
        raise PanomapError("it holds no video stream", held.name)
    return container


def display_image(image: NDArray[Any]) -> NDArray[np.uint8]:
    """An image as 8-bit BGR or BGRA for the page: 16-bit scaled to 8, float clipped to [0, 1]."""
    if image.dtype == np.uint16:
        image = (image.astype(np.float32) / 257.0 + 0.5).astype(np.uint8)
    elif image.dtype != np.uint8:
        image = (np.clip(np.nan_to_num(image), 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)
    return np.ascontiguousarray(image)


def open_source(name: str) -> Source:
    """Read what ``name`` is: an image, a video file or a live source (a URL or ``/dev/videoN``).

    Raises
    ------
    PanomapError
        Naming the input, when it is neither an image nor a video, or cannot be opened.
    """
    if not is_live(name):
        if not Path(name).is_file():
            raise PanomapError("no such file" if not Path(name).exists() else "not a file", name)
        try:
            image = display_image(read_image(name))
        except PanomapError as exc:
            if exc.detail != UNKNOWN_FORMAT:
                raise
        else:
            height, width = image.shape[:2]
            return Source(name, "image", (width, height), image_png=encode_png(image))
    container = open_input(name)
    try:
        source = _video_source(name, container)
    except BaseException:
        container.close()
        raise
    if source.kind == "live":
        return dataclasses.replace(source, connection=container)
    container.close()
    return source


def _video_source(name: str, container: Any) -> Source:
    stream = container.streams.video[0]
    context = stream.codec_context
    size = (int(context.width), int(context.height))
    if size[0] <= 0 or size[1] <= 0:
        raise PanomapError("its video stream does not say its frame size", name)
    rate = float(stream.average_rate) if stream.average_rate else None
    if is_live(name) and not (container.size or 0) > 0:
        return Source(name, "live", size, frame_rate=rate)
    duration = None
    if container.duration is not None:
        duration = container.duration / av.time_base
    elif stream.duration is not None and stream.time_base is not None:
        duration = float(stream.duration * stream.time_base)
    if duration is not None and not (math.isfinite(duration) and duration > 0):
        duration = None
    return Source(name, "video", size, mime=_browser_mime(container, stream), duration_s=duration, frame_rate=rate)


def _browser_mime(container: Any, stream: Any) -> str | None:
    """The MIME type under which a browser plays this file itself, or None (then the server decodes it)."""
    formats = set(str(container.format.name).split(","))
    codec = stream.codec_context.name
    pixel_format = stream.codec_context.format.name if stream.codec_context.format else None
    if codec not in BROWSER_CODECS or pixel_format not in BROWSER_PIXEL_FORMATS:
        return None
    if formats & {"mp4", "mov"}:
        return "video/mp4"
    if "webm" in formats and codec != "h264":  # (Matroska and WebM share PyAV's name; WebM holds no H.264)
        return "video/webm"
    return None
