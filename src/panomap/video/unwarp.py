"""Unwarping video: decode each frame once, remap it into every view, encode each view.

The pipeline runs in threads joined by bounded queues, so memory stays flat
however long the input::

    reader (demux + threaded decode, PyAV)  --frames-->  remap (this thread)
    remap: every view's precomputed map, once per frame  --frames-->  one writer per view
    writer: encode + mux into its own file (a temporary name, renamed when done)

Audio packets go from the reader to every writer unchanged (stream copy).

Convention: frames are remapped in the decoder's own planar YUV format where
the output is YUV too (no round trip through RGB): the luma plane with the
view's map, each chroma plane with the same map sampled at the chroma
sample centres (the mean of each 2 x 2 or 2 x 1 block of map entries, scaled
to the plane; chroma taken as centred between the luma samples). Otherwise
frames are converted once to BGR, exactly as a still image is read.
Timestamps: every output frame keeps its input frame's timestamp, less the
``start`` offset when one is given (as ``ffmpeg -ss``).
"""

from __future__ import annotations

import contextlib
import math
import os
import queue
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from fractions import Fraction
from pathlib import Path
from typing import Any

import av
import cv2
import numpy as np
from numpy.typing import NDArray

from ..errors import PanomapError
from ..files import atomic_path
from ..remap import Remapper
from ..table.table import PanoMappingTable
from ..views import View, build_map

QUEUE_FRAMES = 4
# OpenCV threads for the remap while a video runs. The decoder's and encoders' threads already
# keep every core busy; OpenCV's pool would only add wake-ups (one thread: 11.7 ms of CPU per
# 2048 x 512 YUV frame, against 12.1-13.7 ms with two).
REMAP_THREADS = 1
# Planar formats remapped plane by plane: log2 chroma subsampling (x, y), and the fill of each plane.
PLANAR_FORMATS: dict[str, tuple[int, int, tuple[int, ...]]] = {
    "yuv420p": (1, 1, (16, 128, 128)),
    "yuvj420p": (1, 1, (0, 128, 128)),
    "yuv422p": (1, 0, (16, 128, 128)),
    "yuvj422p": (1, 0, (0, 128, 128)),
    "yuv444p": (0, 0, (16, 128, 128)),
    "yuvj444p": (0, 0, (0, 128, 128)),
    "gray": (0, 0, (0,)),
}
BGR = "bgr24"
_END = object()


@dataclass(frozen=True)
class EncoderSettings:
    """How each view's video is encoded.

    Parameters
    ----------
    codec : str
        An FFmpeg encoder name (``libx264``, ``libx265``, ``ffv1``, ...).
    pix_fmt : str
        The encoded pixel format (``yuv420p`` plays everywhere).
    crf : int or None
        Constant rate factor for codecs that take one (x264/x265: 0 lossless,
        18 visually lossless, 23 their default); None leaves the codec's.
    preset : str or None
        Speed preset for codecs that take one (x264: ultrafast .. veryslow).
    bitrate : int or None
        Target bit rate (bit/s) instead of a constant quality.
    options : tuple of (key, value)
        Further encoder options, as FFmpeg's ``-KEY VALUE``.
    """

    codec: str = "libx264"
    pix_fmt: str = "yuv420p"
    crf: int | None = 20
    preset: str | None = "veryfast"
    bitrate: int | None = None
    options: tuple[tuple[str, str], ...] = ()

    def codec_options(self) -> dict[str, str]:
        """The options passed to the encoder."""
        takes_crf_preset = self.codec in ("libx264", "libx264rgb", "libx265")
        options: dict[str, str] = {}
        if takes_crf_preset and self.preset is not None:
            options["preset"] = self.preset
        if takes_crf_preset and self.crf is not None and self.bitrate is None:
            options["crf"] = str(self.crf)
        return options | dict(self.options)

    def check(self) -> None:
        """Refuse an unknown encoder or a pixel format it cannot take, before any work."""
        try:
            codec = av.codec.Codec(self.codec, "w")
        except (av.error.FFmpegError, ValueError):
            raise PanomapError(f"unknown video encoder {self.codec!r} (try libx264)") from None
        if codec.type != "video":
            raise PanomapError(f"{self.codec!r} is not a video encoder")
        formats = [f.name for f in codec.video_formats or ()]
        if formats and self.pix_fmt not in formats:
            raise PanomapError(f"the encoder {self.codec} cannot take {self.pix_fmt} (it takes {', '.join(formats)})")


@dataclass(frozen=True)
class Selection:
    """Which frames to read: from ``start`` (s) for ``duration`` (s), every ``every``-th."""

    start: float = 0.0
    duration: float | None = None
    every: int = 1

    def __post_init__(self) -> None:
        if not (math.isfinite(self.start) and self.start >= 0):
            raise PanomapError(f"the start must be a time of at least 0 s, not {self.start:g}")
        if self.duration is not None and not (math.isfinite(self.duration) and self.duration > 0):
            raise PanomapError(f"the duration must be more than 0 s, not {self.duration:g}")
        if self.every < 1:
            raise PanomapError(f"every must be a whole number of at least 1, not {self.every}")


@dataclass
class VideoReport:
    """What a run did: frames read and written, what was skipped and why, how it ended."""

    frames_read: int = 0
    frames_written: int = 0
    frames_skipped: int = 0
    problems: list[str] = field(default_factory=list)
    interrupted: bool = False
    seconds: float = 0.0
    outputs: list[Path] = field(default_factory=list)
    audio: bool = False


# ----------------------------------------------------------------------------- input


def is_live(source: str) -> bool:
    """True for a URL or a capture device: inputs with no end and no seeking."""
    return "://" in source or source.startswith("/dev/")


def open_input(source: str, open_timeout: float = 10.0) -> Any:
    """Open a video file, an RTSP/HTTP URL or a V4L2 device (``/dev/videoN``) with PyAV.

    Raises PanomapError naming the input when it cannot be opened or holds no video.
    """
    options: dict[str, str] = {}
    container_format = None
    if source.startswith("/dev/"):
        container_format = "v4l2"
    elif source.lower().startswith("rtsp://"):
        options["rtsp_transport"] = "tcp"
    elif "://" not in source and not Path(source).is_file():
        raise PanomapError("no such file" if not Path(source).exists() else "not a file", source)
    try:
        container = av.open(source, format=container_format, options=options, timeout=(open_timeout, open_timeout))
    except (av.error.FFmpegError, OSError, ValueError) as exc:
        raise PanomapError(f"cannot open it as a video ({_reason(exc)})", source) from None
    if not container.streams.video:
        container.close()
        raise PanomapError("it holds no video stream", source)
    return container


def _reason(exc: BaseException) -> str:
    return " ".join(str(getattr(exc, "strerror", None) or exc).split())


# ----------------------------------------------------------------------------- remapping frames


def _chroma_map(map_uv: NDArray[np.float32], sub_x: int, sub_y: int) -> NDArray[np.float32]:
    """The map of a chroma plane subsampled by 2**sub_x, 2**sub_y; shape (ceil(H/sy), ceil(W/sx), 2).

    Each chroma sample's entry is the mean of the luma entries it covers (NaN
    if any is), converted to chroma-plane coordinates: ``(u + 0.5)/sx - 0.5``.
    """
    sx, sy = 1 << sub_x, 1 << sub_y
    height, width = map_uv.shape[:2]
    padded = np.pad(map_uv, ((0, -height % sy), (0, -width % sx), (0, 0)), mode="edge")
    blocks = np.zeros((padded.shape[0] // sy, padded.shape[1] // sx, 2), dtype=np.float32)
    for dy in range(sy):
        for dx in range(sx):
            blocks += padded[dy::sy, dx::sx]
    # (mean + 0.5) / s - 0.5, per axis
    blocks *= np.array([1 / (sx * sx * sy), 1 / (sy * sx * sy)], dtype=np.float32)
    blocks += np.array([0.5 / sx - 0.5, 0.5 / sy - 0.5], dtype=np.float32)
    return blocks


class FrameRemapper:
    """One view's maps for frames of one size and pixel format; call it on a decoded frame.

    Parameters
    ----------
    map_uv : (H, W, 2) float32 ndarray
        The view's map (source u, v per output pixel; NaN where none).
    source_size : (width, height)
        The frames' size.
    work_format : str
        A planar format of :data:`PLANAR_FORMATS` (remapped plane by plane)
        or ``bgr24`` (remapped as a still image is).
    interpolation : {"nearest", "linear", "cubic"}
    fixed_point : bool
        Keep the maps in OpenCV's fixed-point form (see :class:`Remapper`): a
        third less memory, positions rounded to 1/32 px, and on OpenCV 5.0
        about twice as slow on one-channel planes (6.7 against 12.5 ms for a
        2048 x 512 panorama's Y, U and V planes), hence off by default.
    """

    def __init__(
        self,
        map_uv: NDArray[np.float32],
        source_size: tuple[int, int],
        work_format: str,
        interpolation: str = "linear",
        fixed_point: bool = False,
    ) -> None:
        self.work_format = work_format
        self.output_size = (map_uv.shape[1], map_uv.shape[0])
        width, height = source_size
        if work_format == BGR:
            self._planes = [Remapper(map_uv, source_size, interpolation, 0.0, fixed_point)]
            return
        check_output_size(work_format, self.output_size)
        sub_x, sub_y, fills = PLANAR_FORMATS[work_format]
        chroma = _chroma_map(map_uv, sub_x, sub_y) if len(fills) > 1 else map_uv
        chroma_size = (-(-width >> sub_x), -(-height >> sub_y))
        self._planes = [
            Remapper(map_uv, source_size, interpolation, float(fills[0]), fixed_point),
            *(Remapper(chroma, chroma_size, interpolation, float(fill), fixed_point) for fill in fills[1:]),
        ]

    def __call__(self, frame: Any) -> Any:
        """Remap one decoded ``av.VideoFrame`` (already in the work format); a new frame out."""
        width, height = self.output_size
        if self.work_format == BGR:
            out = av.VideoFrame.from_ndarray(self._planes[0](frame.to_ndarray(format=BGR)), format=BGR)
        else:
            out = av.VideoFrame(width, height, self.work_format)
            for remapper, source, target in zip(self._planes, frame.planes, out.planes, strict=True):
                remapper(_plane_array(source), out=_plane_array(target))
        out.pts = frame.pts
        if frame.time_base is not None:
            out.time_base = frame.time_base
        return out


def check_output_size(work_format: str, size: tuple[int, int]) -> None:
    """Refuse a view size (W, H) that the work format's chroma subsampling does not divide."""
    if work_format not in PLANAR_FORMATS:
        return
    sub_x, sub_y, _ = PLANAR_FORMATS[work_format]
    width, height = size
    if width % (1 << sub_x) or height % (1 << sub_y):
        even = (width >> sub_x << sub_x, height >> sub_y << sub_y)
        raise PanomapError(
            f"{work_format} needs an output size divisible by {1 << sub_x} x {1 << sub_y}, "
            f"not {width} x {height}: give the view a size such as size={even[0]}x{even[1]}"
        )


def _plane_array(plane: Any) -> NDArray[np.uint8]:
    """An (h, w) uint8 view of a frame plane (rows padded to its line size in memory)."""
    return np.frombuffer(plane, np.uint8).reshape(plane.height, plane.line_size)[:, : plane.width]


def work_format(input_format: str, output_format: str) -> str:
    """The format frames are remapped in: the decoder's own where it and the output are YUV."""
    output_is_rgb = av.VideoFormat(output_format).is_rgb
    if not output_is_rgb and input_format in PLANAR_FORMATS:
        return input_format
    if not output_is_rgb and output_format in PLANAR_FORMATS:
        return output_format
    return BGR


# ----------------------------------------------------------------------------- output


@dataclass
class _Writer:
    """One view's output: its container (under a temporary name), streams and thread."""

    path: Path
    temporary: Path
    container: Any
    video: Any
    audio: Any | None
    inbox: queue.Queue[Any] = field(default_factory=lambda: queue.Queue(QUEUE_FRAMES))
    error: BaseException | None = None
    frames: int = 0
    thread: threading.Thread | None = None

    def run(self, stop: threading.Event) -> None:
        try:
            while True:
                item = self.inbox.get()
                if item is _END:
                    break
                if isinstance(item, av.Packet):
                    item.stream = self.audio
                    self.container.mux(item)
                    continue
                for packet in self.video.encode(item):
                    self.container.mux(packet)
                self.frames += 1
            for packet in self.video.encode(None):
                self.container.mux(packet)
        except BaseException as exc:  # reported by the caller
            self.error = exc
            stop.set()
            with contextlib.suppress(queue.Empty):
                while True:  # unblock the producer
                    self.inbox.get_nowait()


def _open_writer(
    path: Path,
    temporary: Path,
    size: tuple[int, int],
    rate: Fraction | None,
    time_base: Fraction,
    encoder: EncoderSettings,
    audio_template: Any | None,
) -> _Writer:
    try:
        container = av.open(str(temporary), "w", format=_container_format(path))
    except (av.error.FFmpegError, OSError, ValueError) as exc:
        raise PanomapError(f"cannot write a video there ({_reason(exc)})", path) from None
    try:
        video: Any = container.add_stream(encoder.codec, rate=rate or Fraction(25))
        video.width, video.height = size
        video.pix_fmt = encoder.pix_fmt
        video.time_base = time_base
        video.codec_context.time_base = time_base
        if encoder.bitrate is not None:
            video.bit_rate = encoder.bitrate
        video.options = encoder.codec_options()
        audio: Any = container.add_stream_from_template(audio_template) if audio_template is not None else None
        container.start_encoding()
    except (av.error.FFmpegError, ValueError, TypeError) as exc:
        container.close()
        what = "with the input's audio " if audio_template is not None else ""
        hint = " (try --no-audio)" if audio_template is not None else ""
        raise PanomapError(
            f"cannot encode {encoder.codec} {encoder.pix_fmt} {what}into it: {_reason(exc)}{hint}", path
        ) from None
    return _Writer(path, temporary, container, video, audio)


def _container_format(path: Path) -> str | None:
    suffix = path.suffix.lower()
    known = {
        ".mp4": "mp4",
        ".m4v": "mp4",
        ".mov": "mov",
        ".mkv": "matroska",
        ".webm": "webm",
        ".avi": "avi",
        ".ts": "mpegts",
        ".nut": "nut",
    }
    if suffix not in known:
        raise PanomapError(
            f"unknown video file type {suffix or '(none)'!r}: use .mp4, .mkv, .mov, .webm, .avi, .ts", path
        )
    return known[suffix]


# ----------------------------------------------------------------------------- the pipeline


@dataclass(frozen=True)
class ViewOutput:
    """A view and the file it goes to."""

    view: View
    path: Path


def unwarp_video(
    table: PanoMappingTable,
    source: str,
    outputs: Sequence[ViewOutput],
    *,
    encoder: EncoderSettings = EncoderSettings(),
    selection: Selection = Selection(),
    audio: bool = True,
    sampling: str = "bilinear",
    interpolation: str = "linear",
    fixed_point: bool = False,
    stop: threading.Event | None = None,
    progress: Callable[[int, int | None], None] | None = None,
    warn: Callable[[str], None] | None = None,
) -> VideoReport:
    """Unwarp ``source`` into one video per view; returns what was done.

    Everything that can be checked is checked before the first frame is read:
    the input opens and holds video of the table's image size, the encoder
    takes the pixel format and the view sizes, and every output can be
    created; the maps are built while the first frames decode, and a view
    they refuse (a floor the camera cannot see) ends the run with no output. A frame that
    fails to decode is reported (``warn``) and skipped; damage that ends the
    input ends the run with the frames before it. Setting ``stop`` (as the CLI
    does on SIGINT/SIGTERM) ends the run cleanly: every output is finished
    and playable. ``progress(frames_done, frames_expected_or_None)`` is called
    after each frame. OpenCV runs on :data:`REMAP_THREADS` thread(s) during the
    call (process-wide, as ``cv2.setNumThreads`` is); the caller's setting is
    restored after.
    """
    stop = stop or threading.Event()
    warn = warn or (lambda message: None)
    encoder.check()
    paths = [item.path for item in outputs]
    if len(set(paths)) != len(paths):
        raise PanomapError("two views would write the same file: put {name} in the output pattern")
    for path in paths:
        _container_format(path)
        folder = path.parent if str(path.parent) else Path(".")
        if not folder.is_dir():
            raise PanomapError("its folder does not exist", path)
        if not os.access(folder, os.W_OK | os.X_OK):
            raise PanomapError("its folder is not writable", path)
    container = open_input(source)
    report = VideoReport()
    started = time.perf_counter()
    try:
        stream = container.streams.video[0]
        stream.thread_type = "AUTO"
        size = (stream.codec_context.width, stream.codec_context.height)
        if table.image_size is not None and size != tuple(table.image_size):
            raise PanomapError(
                f"its frames are {size[0]} x {size[1]}, the table is for "
                f"{table.image_size[0]} x {table.image_size[1]} images",
                source,
            )
        in_format = stream.codec_context.pix_fmt or "yuv420p"
        work = work_format(in_format, encoder.pix_fmt)
        sizes = [item.view.output_size(table) for item in outputs]
        for view_size in sizes:
            check_output_size(work, view_size)

        def build_remappers() -> list[FrameRemapper]:
            """Made while the first frames decode (a few tenths of a second saved at start-up)."""
            maps = [build_map(table, item.view, sampling) for item in outputs]
            return [FrameRemapper(map_uv, size, work, interpolation, fixed_point) for map_uv in maps]

        audio_stream = container.streams.audio[0] if audio and container.streams.audio else None
        report.audio = audio_stream is not None
        rate = stream.average_rate or stream.guessed_rate
        if rate is not None and selection.every > 1:
            rate = Fraction(rate) / selection.every
        time_base = stream.time_base or Fraction(1, 90000)
        with contextlib.ExitStack() as files:
            writers: list[_Writer] = []
            try:
                for item, view_size in zip(outputs, sizes, strict=True):
                    temporary = files.enter_context(atomic_path(item.path))
                    writers.append(
                        _open_writer(item.path, temporary, view_size, rate, time_base, encoder, audio_stream)
                    )
                with _opencv_threads(REMAP_THREADS):
                    _run(
                        container,
                        stream,
                        audio_stream,
                        work,
                        build_remappers,
                        writers,
                        selection,
                        stop,
                        progress,
                        warn,
                        report,
                    )
            finally:
                for writer in writers:
                    with contextlib.suppress(av.error.FFmpegError):
                        writer.container.close()
            failed = next((writer for writer in writers if writer.error is not None), None)
            if failed is not None:
                raise PanomapError(f"writing failed ({_reason(failed.error)})", failed.path)  # type: ignore[arg-type]
            if report.frames_written == 0:
                raise PanomapError("no frame could be decoded (nothing written)", source)
        report.outputs = paths
    finally:
        container.close()
        report.seconds = time.perf_counter() - started
    return report


@contextlib.contextmanager
def _opencv_threads(count: int) -> Iterator[None]:
    """Run the block with OpenCV using ``count`` threads, then give back the caller's setting."""
    before = cv2.getNumThreads()
    cv2.setNumThreads(count)
    try:
        yield
    finally:
        cv2.setNumThreads(before)


def _expected_frames(stream: Any, selection: Selection, live: bool) -> int | None:
    if live:
        return None
    rate = stream.average_rate or stream.guessed_rate
    total = stream.frames or 0
    if not total and stream.duration and stream.time_base and rate:
        total = round(float(stream.duration * stream.time_base * rate))
    if not total or not rate:
        return None
    first = min(total, round(selection.start * float(rate)))
    last = total if selection.duration is None else min(total, first + round(selection.duration * float(rate)))
    return max(0, -(-(last - first) // selection.every))


def _put(box: queue.Queue[Any], item: Any, give_up: Callable[[], bool]) -> bool:
    """Put ``item`` on a bounded queue, waiting while it is full unless ``give_up()``; True when put."""
    while True:
        try:
            box.put(item, timeout=0.1)
            return True
        except queue.Full:
            if give_up():
                return False


def _run(
    container: Any,
    stream: Any,
    audio_stream: Any | None,
    work: str,
    build_remappers: Callable[[], list[FrameRemapper]],
    writers: list[_Writer],
    selection: Selection,
    stop: threading.Event,
    progress: Callable[[int, int | None], None] | None,
    warn: Callable[[str], None],
    report: VideoReport,
) -> None:
    """Run reader, remapping (here) and writers until the input ends, ``stop`` is set or a writer fails."""
    frames: queue.Queue[Any] = queue.Queue(QUEUE_FRAMES)
    halt = threading.Event()  # stop, a writer's failure, or the end of the run
    expected = _expected_frames(stream, selection, is_live(str(container.name)))
    for writer in writers:
        writer.thread = threading.Thread(
            target=writer.run, args=(halt,), name=f"panomap-write-{writer.path.name}", daemon=True
        )
        writer.thread.start()

    def halted() -> bool:
        return halt.is_set() or stop.is_set()

    def on_audio(packet: Any) -> None:
        for writer in writers:
            _put(writer.inbox, _copy_packet(packet), halted)

    reader = threading.Thread(
        target=_read,
        args=(container, stream, audio_stream, work, selection, frames, halted, on_audio, warn, report),
        name="panomap-read",
        daemon=True,
    )
    reader.start()
    try:
        remappers = build_remappers()
        while not halted():
            try:
                frame = frames.get(timeout=0.1)
            except queue.Empty:
                continue
            if frame is _END:
                break
            for remapper, writer in zip(remappers, writers, strict=True):
                _put(writer.inbox, remapper(frame), lambda w=writer: w.error is not None)  # type: ignore[misc]
            report.frames_written += 1
            if progress is not None:
                progress(report.frames_written, expected)
    finally:
        report.interrupted = stop.is_set() and all(writer.error is None for writer in writers)
        halt.set()
        while reader.is_alive():  # let the reader see the halt, even if it waits on a full queue
            with contextlib.suppress(queue.Empty):
                frames.get(timeout=0.1)
        for writer in writers:
            _put(writer.inbox, _END, lambda w=writer: w.error is not None)  # type: ignore[misc]
        for writer in writers:
            assert writer.thread is not None
            writer.thread.join()


def _copy_packet(packet: Any) -> Any:
    """A packet of its own for each writer (muxing takes a packet's data)."""
    copy = av.Packet(bytes(packet))
    copy.pts, copy.dts, copy.time_base = packet.pts, packet.dts, packet.time_base
    copy.duration = packet.duration
    copy.is_keyframe = packet.is_keyframe
    return copy


def _read(
    container: Any,
    stream: Any,
    audio_stream: Any | None,
    work: str,
    selection: Selection,
    frames: queue.Queue[Any],
    halted: Callable[[], bool],
    on_audio: Callable[[Any], None],
    warn: Callable[[str], None],
    report: VideoReport,
) -> None:
    """Demux and decode, putting the selected frames (in the work format) on ``frames``; _END last.

    Times are measured from the stream's start (files) or its first frame (live inputs).
    """
    source = str(container.name)
    time_base = stream.time_base
    live = is_live(source)
    origin: float | None = None if live else _stream_start(stream)
    if selection.start > 0 and not live:
        with contextlib.suppress(av.error.FFmpegError):
            container.seek(int((selection.start + _stream_start(stream)) / time_base), stream=stream, backward=True)
    # Seconds subtracted from every timestamp: the start (from the first frame, on a live input).
    shift = 0.0 if selection.start == 0 else (None if origin is None else origin + selection.start)
    index = 0
    streams = [stream] + ([audio_stream] if audio_stream is not None else [])

    def window(seconds: float) -> int:
        """-1 before the selection, 0 inside, 1 after it."""
        assert origin is not None
        if selection.start > 0 and seconds < origin + selection.start - 1e-9:
            return -1  # (from the very start, everything counts: audio priming has negative times)
        if selection.duration is not None and seconds >= origin + selection.start + selection.duration - 1e-9:
            return 1
        return 0

    try:
        for packet in _demux(container, streams, warn):
            if halted():
                return
            if packet.stream.type == "audio":
                if packet.pts is None or packet.dts is None or origin is None:
                    continue
                if window(float(packet.pts * packet.time_base)) == 0 and shift is not None:
                    ticks = round(shift / float(packet.time_base))
                    packet.pts -= ticks
                    packet.dts -= ticks
                    on_audio(packet)
                continue
            try:
                decoded = packet.decode()
            except av.error.FFmpegError as exc:
                report.frames_skipped += 1
                warn(f"{source}: skipped a frame that does not decode at {_when(packet, time_base)} ({_reason(exc)})")
                continue
            for frame in decoded:
                if frame.pts is None:
                    continue
                seconds = float(frame.pts * time_base)
                if origin is None:
                    origin = seconds
                place = window(seconds)
                if place < 0:
                    continue
                if place > 0:
                    return
                report.frames_read += 1
                if shift is None:
                    shift = origin + selection.start
                index += 1
                if (index - 1) % selection.every:
                    continue
                frame.pts -= round(shift / float(time_base))
                if frame.format.name != work:
                    frame = frame.reformat(format=work)
                if not _put(frames, frame, halted):
                    return
    except Exception as exc:  # reading ends; what was read is kept
        report.problems.append(f"{source}: reading stopped: {_reason(exc)}")
        warn(report.problems[-1])
    finally:
        _put(frames, _END, halted)


def _demux(container: Any, streams: list[Any], warn: Callable[[str], None]) -> Iterator[Any]:
    """Packets of ``streams``; a damaged stretch is reported and demuxing resumes after it, if it can."""
    failures = 0
    while True:
        try:
            for packet in container.demux(streams):
                failures = 0
                yield packet  # the last, empty, one drains the decoder
            return
        except av.error.EOFError:
            return
        except av.error.FFmpegError as exc:
            failures += 1
            warn(f"{container.name}: damaged data skipped ({_reason(exc)})")
            if failures >= 3:
                raise


def _stream_start(stream: Any) -> float:
    return float(stream.start_time * stream.time_base) if stream.start_time is not None else 0.0


def _when(packet: Any, time_base: Fraction) -> str:
    return f"{float(packet.pts * time_base):.3f} s" if packet.pts is not None else "an unknown time"
