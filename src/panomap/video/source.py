"""The input: open a file, stream or device, select frames (start, duration, every) and read them.

Timestamps: every frame keeps its input timestamp, less the ``start`` offset when one is given
(as ``ffmpeg -ss``). Damage is reported and skipped. A live input that drops (see
:mod:`panomap.video.live`) is read again after it reconnects: the selection goes on where it
was, counting only the time received.
"""

from __future__ import annotations

import contextlib
import math
import queue
import threading
import time
import warnings
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path
from typing import Any

import av

from .. import inputs
from ..errors import PanomapError
from .handoff import END, put, reason
from .report import VideoReport


@dataclass(frozen=True, init=False)
class Selection:
    """Which frames to read: from ``start_s`` (s) for ``duration`` (s), every ``every``-th.

    ``start`` is the old spelling of ``start_s``: still taken and read, with a DeprecationWarning.
    """

    start_s: float = 0.0
    duration: float | None = None
    every: int = 1

    def __init__(
        self, start_s: float = 0.0, duration: float | None = None, every: int = 1, *, start: float | None = None
    ) -> None:
        if start is not None:
            warnings.warn("Selection(start=...) is deprecated: the field is start_s", DeprecationWarning, stacklevel=2)
            start_s = start
        object.__setattr__(self, "start_s", start_s)
        object.__setattr__(self, "duration", duration)
        object.__setattr__(self, "every", every)
        self.__post_init__()

    @property
    def start(self) -> float:
        """The old spelling of ``start_s`` (s), with a DeprecationWarning."""
        warnings.warn("Selection.start is deprecated: the field is start_s", DeprecationWarning, stacklevel=2)
        return self.start_s

    def __post_init__(self) -> None:
        inputs.number(self.start_s, "the start (s)")
        if self.duration is not None:
            inputs.number(self.duration, "the duration (s)", limit=math.inf)
        inputs.whole_numbers((self.every,), 1, "every (frames)")
        if not (math.isfinite(self.start_s) and self.start_s >= 0):
            raise PanomapError(f"the start must be a time of at least 0 s, not {self.start_s:g}")
        if self.duration is not None and not (math.isfinite(self.duration) and self.duration > 0):
            raise PanomapError(f"the duration must be more than 0 s, not {self.duration:g}")
        if self.every < 1:
            raise PanomapError(f"every must be a whole number of at least 1, not {self.every}")


def is_live(source: str) -> bool:
    """True for a URL or a capture device: inputs with no end and no seeking."""
    return "://" in source or source.startswith("/dev/")


def frame_size(stream: Any, source: str) -> tuple[int, int]:
    """The video ``stream``'s frame size (W, H) from its header; PanomapError naming ``source`` where the header
    gives none (a file FFmpeg opens that is no video: a text file named .jpg, a broken header)."""
    size = (stream.codec_context.width, stream.codec_context.height)
    if 0 in size:
        raise PanomapError(
            "cannot read it as a video (its header gives no frame size: not a video, or corrupt)", source
        )
    return size


def open_input(source: str, open_timeout: float = 10.0, read_timeout: float | None = None) -> Any:
    """Open a video file, an RTSP/HTTP URL or a V4L2 device (``/dev/videoN``) with PyAV.

    ``open_timeout`` and ``read_timeout`` (s; default: the open timeout) bound
    how long opening and each read of a network input may wait. Raises
    PanomapError naming the input when it cannot be opened or holds no video.
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
        container = av.open(
            source, format=container_format, options=options, timeout=(open_timeout, read_timeout or open_timeout)
        )
    except (av.error.FFmpegError, OSError, ValueError) as exc:
        raise PanomapError(f"cannot open it as a video ({reason(exc)})", source) from None
    if not container.streams.video:
        container.close()
        raise PanomapError("it holds no video stream", source)
    return container


def rotation_note(path: str | Path) -> str | None:
    """A warning where the video file asks players to turn its frames (a display matrix, or an old ``rotate``
    tag); None otherwise or where it cannot be read (its reader says why).

    panomap takes the frames as stored, as it takes an image's pixels whatever its EXIF orientation: landmarks
    measured in a player that turned the video would not match them.
    """
    try:
        with av.open(str(path)) as container:
            if not container.streams.video:
                return None
            stream = container.streams.video[0]
            tag = stream.metadata.get("rotate")
            degrees = float(tag) if tag is not None else None
            if degrees is None:
                frame = next(iter(container.decode(stream)), None)
                degrees = float(getattr(frame, "rotation", 0) or 0) if frame is not None else 0.0
    except (av.error.FFmpegError, OSError, ValueError, StopIteration):
        return None
    degrees = degrees % 360
    if degrees == 0:
        return None
    return (
        f"it asks players to turn its frames by {degrees:g} deg (its rotation metadata): panomap takes the frames "
        "as stored, so measure landmarks in the frames as stored, not as a player shows them"
    )


def first_frame(path: str | Path, max_pixels: int, at_s: float | None = None) -> Any:
    """The first frame of a video file (at or after ``at_s`` seconds from its start, where given) as an 8-bit
    BGR image (H, W, 3), or None where the file is not a video PyAV decodes (for the commands that take one
    omni-image: any frame of the camera serves them).

    Raises
    ------
    PanomapError
        Naming the file, when its frames are larger than ``max_pixels`` (refused before decoding one), or
        when it has no frame at or after ``at_s``.
    """
    try:
        with av.open(str(path)) as container:
            if not container.streams.video:
                return None
            stream = container.streams.video[0]
            width, height = stream.codec_context.width, stream.codec_context.height
            if width * height > max_pixels:
                raise PanomapError(f"its frames are {width} x {height}: larger than panomap reads", path)
            start = _stream_start(stream)
            if at_s:
                seek_before(container, stream, at_s)
            half_frame = 0.5 / float(stream.average_rate or 25)
            decoded = False
            for count, frame in enumerate(container.decode(stream)):
                decoded = True
                if at_s and frame_seconds(frame, count, stream) - start < at_s - half_frame:
                    continue
                return frame.to_ndarray(format="bgr24")
    except (av.error.FFmpegError, OSError, ValueError):
        return None
    if at_s and decoded:
        raise PanomapError(f"it has no frame at or after {at_s:g} s", path)
    return None


class SharedInput:
    """An opened input and the threads that read it: closed only once no thread is inside it.

    FFmpeg frees the demuxer on close, so a close while another thread waits in
    its read (a live input that sends nothing) would crash the process. A
    reader :meth:`hold` s the input before it starts and :meth:`release` s it
    when it has returned; :meth:`close` closes at once when no reader holds it,
    and otherwise leaves the close to the last reader to return (as when a run
    is aborted while its reader waits: the reader ends at its read timeout, or
    with the process).
    """

    def __init__(self, container: Any) -> None:
        self.container = container
        self._lock = threading.Lock()
        self._readers = 0
        self._closing = False

    def hold(self) -> None:
        with self._lock:
            self._readers += 1

    def release(self) -> None:
        with self._lock:
            self._readers -= 1
            now = self._closing and self._readers == 0
        if now:
            self.container.close()

    def close(self) -> None:
        with self._lock:
            self._closing = True
            now = self._readers == 0
        if now:
            self.container.close()


def drops(source: str, container: Any) -> bool:
    """True for a live input of unknown length: its end, a read error or a silence is a drop.

    A file served over HTTP (its size known) ends at its end, as a file does.
    """
    return is_live(source) and not (container.size or 0) > 0


@dataclass
class ReadState:
    """What reading has seen, kept from one connection of a live input to the next.

    Times in seconds: ``received_s`` of input (from the first frame, the
    selection's clock) and wall-clock ``time.monotonic()`` instants.
    """

    received_s: float = 0.0  # input seconds received before this connection, and in it so far
    index: int = 0  # frames inside the selection so far (for ``every``)
    first_frame_at: float | None = None  # when this connection's first frame came
    last_frame_at: float | None = None  # when the last frame came (any connection)
    dropped: str | None = None  # why this connection dropped; None if it ended otherwise
    ended: bool = False  # the selection's end was reached: nothing more to read
    last_input_s: float | None = None  # input time of the last video frame decoded, from the stream's start
    at_end: bool = False  # the input was read to its end (not stopped, not cut by the selection)

    def next_connection(self) -> None:
        self.first_frame_at = None
        self.dropped = None


def declared_duration_s(container: Any) -> float | None:
    """How long a file's header says its video lasts (s, from the stream's start), or None where it does not
    say: the video stream's duration (MP4) or else the container's (Matroska)."""
    stream = container.streams.video[0]
    if stream.duration and stream.time_base:
        return float(stream.duration * stream.time_base)
    if container.duration:
        return float(container.duration) / 1e6
    return None


def frame_rate(container: Any) -> float:
    """The video stream's frame rate (frames/s; 25 where the file does not say)."""
    stream = container.streams.video[0]
    return float(stream.average_rate or stream.guessed_rate or 25)


def ended_early(declared_end: float | None, rate: float, state: ReadState) -> str | None:
    """A sentence saying that a file's frames stopped well before the end ``declared_end`` (s from the
    stream's start, :func:`declared_duration_s`) that its header declares (a file cut short: a copy or a
    recording that did not finish), or None. "Well": by more than three frames (``rate`` frames/s) and a
    quarter of a second (audio may run a little past the video)."""
    if declared_end is None or state.last_input_s is None:
        return None
    missing = declared_end - (state.last_input_s + 1 / rate)
    if missing <= max(3 / rate, 0.25):
        return None
    return (
        f"the input ended early: its last frame is at {state.last_input_s:.2f} s, its header says "
        f"{declared_end:.2f} s (a truncated or damaged file?)"
    )


def expected_frames(stream: Any, selection: Selection, live: bool) -> int | None:
    if live:
        return None
    rate = stream.average_rate or stream.guessed_rate
    total = stream.frames or 0
    if not total and stream.duration and stream.time_base and rate:
        total = round(float(stream.duration * stream.time_base * rate))
    if not total or not rate:
        return None
    first = min(total, round(selection.start_s * float(rate)))
    last = total if selection.duration is None else min(total, first + round(selection.duration * float(rate)))
    return max(0, -(-(last - first) // selection.every))


def copy_packet(packet: Any) -> Any:
    """A packet of its own for each writer (muxing takes a packet's data)."""
    copy = av.Packet(bytes(packet))
    copy.pts, copy.dts, copy.time_base = packet.pts, packet.dts, packet.time_base
    copy.duration = packet.duration
    copy.is_keyframe = packet.is_keyframe
    return copy


def read_frames(
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
    state: ReadState | None = None,
    drop_timeout_s: float | None = None,
) -> None:
    """Demux and decode, putting the selected frames (in the work format) on ``frames``; END last.

    Times are measured from the stream's start (files) or its first frame (live inputs).
    With ``drop_timeout_s`` (a live input that can drop, read with that timeout), the
    input's end, a read error or a silence is recorded as a drop in ``state.dropped``
    instead of reported; ``state`` carries the selection over to the next connection.
    """
    source = str(container.name)
    state = state or ReadState()
    state.next_connection()
    time_base = stream.time_base
    live = is_live(source)
    # Input time of the selection's zero: the stream's start (files), the first frame less
    # what earlier connections gave (live inputs).
    origin: float | None = None if live else _stream_start(stream)
    if selection.start_s > 0 and not live:
        with contextlib.suppress(av.error.FFmpegError):
            seek_before(container, stream, selection.start_s)
    untimed = 0  # frames decoded without a timestamp (raw H.264), timed by their count
    # Seconds subtracted from every timestamp: the start (from the first frame, on a live input).
    shift = 0.0 if selection.start_s == 0 else (None if origin is None else origin + selection.start_s)
    streams = [stream] + ([audio_stream] if audio_stream is not None else [])
    can_drop = drop_timeout_s is not None

    def window(seconds: float) -> int:
        """-1 before the selection, 0 inside, 1 after it."""
        assert origin is not None
        if selection.start_s > 0 and seconds < origin + selection.start_s - 1e-9:
            return -1  # (from the very start, everything counts: audio priming has negative times)
        if selection.duration is not None and seconds >= origin + selection.start_s + selection.duration - 1e-9:
            return 1
        return 0

    try:
        for packet in _demux(container, streams, warn, can_drop):
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
                warn(f"{source}: skipped a frame that does not decode at {_when(packet, time_base)} ({reason(exc)})")
                continue
            for frame in decoded:
                if frame.pts is None:
                    if live or not time_base:
                        continue
                    frame.pts = round(frame_seconds(frame, untimed, stream) / float(time_base))
                    untimed += 1
                seconds = float(frame.pts * time_base)
                if origin is None:
                    origin = seconds - state.received_s
                state.last_input_s = seconds - origin
                if live:
                    state.received_s = max(state.received_s, seconds - origin)
                place = window(seconds)
                if place < 0:
                    continue
                if place > 0:
                    state.ended = True
                    return
                report.frames_read += 1
                if shift is None:
                    shift = origin + selection.start_s
                state.index += 1
                if (state.index - 1) % selection.every:
                    continue
                frame.pts -= round(shift / float(time_base))
                if frame.format.name != work:
                    frame = frame.reformat(format=work)
                state.last_frame_at = time.monotonic()
                if state.first_frame_at is None:
                    state.first_frame_at = state.last_frame_at
                if not put(frames, frame, halted):
                    return
        if can_drop and not halted():
            state.dropped = "the stream ended"
        state.at_end = not halted()
    except Exception as exc:  # reading ends; what was read is kept
        if can_drop:
            state.dropped = f"no data for {drop_timeout_s:g} s" if isinstance(exc, av.error.ExitError) else reason(exc)
        else:
            report.problems.append(f"{source}: reading stopped: {reason(exc)}")
            warn(report.problems[-1])
    finally:
        put(frames, END, halted)


def _demux(container: Any, streams: list[Any], warn: Callable[[str], None], can_drop: bool = False) -> Iterator[Any]:
    """Packets of ``streams``; a damaged stretch is reported and demuxing resumes after it, if it can.

    With ``can_drop``, a failure to read (a lost connection, a timeout) is raised at once.
    """
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
            if can_drop and isinstance(exc, OSError | av.error.ExitError):
                raise
            failures += 1
            warn(f"{container.name}: damaged data skipped ({reason(exc)})")
            if failures >= 3:
                raise


def _stream_start(stream: Any) -> float:
    return float(stream.start_time * stream.time_base) if stream.start_time is not None else 0.0


# Seconds before a time that a seek goes back on a second try, then a third, when the first lands after the
# time: a stream without an index (MPEG-TS, raw H.264) is seeked by byte position, which lands a keyframe or
# more past where it was asked; failing those, the stream is read from its start.
SEEK_RETRIES_S = (1.0, 4.0)


def seek_before(container: Any, stream: Any, at_s: float) -> bool:
    """Seek ``container`` to a keyframe of ``stream`` at or before ``at_s`` s from the stream's start, as
    ffmpeg seeks a stream without an index: a try at the time, then earlier, checked against the first
    packet read; else back to the start. Returns whether it left the start (the caller decodes forward to
    ``at_s`` either way, dropping the frames before it).

    A stream without timestamps (raw H.264) is not seeked (a failed seek leaves the demuxer at its end):
    its frames are timed by their count (:func:`frame_seconds`).
    """
    if stream.start_time is None or not stream.time_base:
        return False
    start, time_base = _stream_start(stream), stream.time_base
    for back in (0.0, *SEEK_RETRIES_S):
        if at_s - back <= 0:
            break
        try:
            container.seek(int((start + at_s - back) / time_base), stream=stream, backward=True)
            first = next((packet for packet in container.demux(stream) if packet.pts is not None), None)
        except (av.error.FFmpegError, StopIteration):
            break
        # (A byte seek can land on a packet that is no keyframe: nothing decodes until the next one.)
        if first is not None and first.is_keyframe and float(first.pts * time_base) - start <= at_s + 1e-9:
            container.seek(int((start + at_s - back) / time_base), stream=stream, backward=True)
            return True
    container.seek(0)  # (the container's own start: a stream's start_time, seeked in MPEG-TS, read nothing more)
    return False


def frame_seconds(frame: Any, count: int, stream: Any) -> float:
    """The time (s, input's clock) of ``frame``, the ``count``-th decoded from the start: its timestamp, or for a
    stream without timestamps (raw H.264) its place at the stream's frame rate."""
    if frame.pts is not None:
        return float(frame.pts * stream.time_base)
    return count / float(stream.average_rate or stream.guessed_rate or 25)


def _when(packet: Any, time_base: Fraction) -> str:
    return f"{float(packet.pts * time_base):.3f} s" if packet.pts is not None else "an unknown time"
