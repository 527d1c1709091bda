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

A live input that drops is reconnected (:mod:`panomap.video.live`): each
connection writes its own *segment*, a complete file per view (``out.mp4``,
then ``out_001.mp4``, ...), and every gap is recorded in the report.
"""

from __future__ import annotations

import contextlib
import math
import os
import queue
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from fractions import Fraction
from pathlib import Path
from typing import Any

from .. import inputs
from ..errors import PanomapError
from ..files import all_or_none, atomic_path, check_output_paths, local_file
from ..table.table import PanoMappingTable, check_table
from ..views import View, build_map
from .frames import REMAP_THREADS, FrameRemapper, check_output_size, opencv_threads, work_format
from .handoff import END, QUEUE_FRAMES, put, reason
from .live import Reconnect, check_segment_names, segment_path
from .output import EncoderSettings, Writer, container_format, open_writer
from .report import Gap, GapOutcome, VideoReport
from .source import (
    ReadState,
    Selection,
    SharedInput,
    copy_packet,
    declared_duration_s,
    drops,
    ended_early,
    expected_frames,
    frame_rate,
    frame_size,
    is_live,
    open_input,
    read_frames,
)

# ----------------------------------------------------------------------------- input


@dataclass(frozen=True)
class ViewOutput:
    """A view and the file it goes to."""

    view: View
    path: Path


def _check_arguments(table: Any, outputs: Any, memory_limit: Any) -> None:
    """Refuse, before the video is opened, what :func:`unwarp_video` cannot use: no table, no view to write."""
    check_table(table)
    if isinstance(outputs, ViewOutput) or not isinstance(outputs, Sequence) or isinstance(outputs, str):
        raise TypeError(f"outputs must be a list of ViewOutput(view, path), not {type(outputs).__name__}")
    if not outputs:
        raise PanomapError("no view to write: give at least one ViewOutput(view, path)")
    for k, item in enumerate(outputs):
        inputs.instance(item, ViewOutput, f"outputs[{k}]", " (ViewOutput(view, path))")
        inputs.instance(item.view, View, f"outputs[{k}].view")
        inputs.path(item.path, f"outputs[{k}].path")
    if memory_limit is not None and inputs.number(memory_limit, "memory_limit (bytes)", limit=math.inf) <= 0:
        raise PanomapError(f"memory_limit must be more than 0 bytes, not {memory_limit}")


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
    memory_limit: int | None = None,
    reconnect: Reconnect = Reconnect(),
    codec_threads: int | None = None,
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
    after each frame. Views whose estimated memory (:func:`check_memory`) is
    beyond ``memory_limit`` bytes (default: 3/4 of the machine's memory) are
    refused before any work. OpenCV runs on :data:`REMAP_THREADS` thread(s) during the
    call (process-wide, as ``cv2.setNumThreads`` is); the caller's setting is
    restored after.

    A live input of unknown length that drops (it ends, fails to read, or
    sends nothing for ``reconnect.timeout_s``) is reconnected with
    exponential backoff (``reconnect``): the files written so far are closed,
    complete, and the run goes on in the next segment's files (``out.mp4``,
    then ``out_001.mp4``, ... :func:`panomap.video.live.segment_path`). Each
    gap is reported (``warn``, one line, once it ends) and kept in
    ``report.gaps``; a run that cannot reconnect returns with its last gap's
    outcome ``"gave up"`` (:attr:`VideoReport.gave_up`), every segment written
    kept. ``stop`` also ends a reconnect wait at once.

    ``codec_threads``: the threads of the decoder and of each encoder (default: FFmpeg's
    choice, about one per core). Where several videos run at once on a machine (the local
    workers of ``panomap batch``), one each keeps the cores as busy with less switching
    between threads (docs/scaling.md). An encoder ``threads`` option in ``encoder`` wins.

    Parameters
    ----------
    table : PanoMappingTable
        The camera's table; the input's frames must be of its image size.
    source : str
        A video file, a URL (``rtsp://``, ``http://``, ``tcp://``, ...) or a capture device (``/dev/video0``).
    outputs : sequence of ViewOutput
        Each view and the file it is written to.
    encoder : EncoderSettings
        The codec, pixel format, quality and container options of every output.
    selection : Selection
        Which frames: a start, a duration, every n-th frame.
    audio : bool
        Copy the input's audio into every output.
    sampling : {"bilinear", "nearest"}
        How the table is read between its entries.
    interpolation : {"linear", "nearest", "cubic"}
        How each frame is read between its pixels.
    fixed_point : bool
        Keep the maps in OpenCV's fixed-point form (less memory, positions rounded to 1/32 px).
    stop : threading.Event, optional
        Set it to end the run cleanly.
    progress : callable, optional
        Called as ``progress(frames_done, frames_expected_or_None)`` after each frame.
    warn : callable, optional
        Called with one line for each frame skipped and each gap of a live input.
    memory_limit : int, optional
        Bytes the views' maps and frames may take (default: 3/4 of the machine's memory).
    reconnect : Reconnect
        How a live input that drops is reconnected (attempts, waits, timeout).
    codec_threads : int, optional
        Threads of the decoder and of each encoder.

    Returns
    -------
    VideoReport
        The frames read and written, the segments' files, the gaps, the time taken.
    """
    _check_arguments(table, outputs, memory_limit)
    stop = stop or threading.Event()
    warn = warn or (lambda message: None)
    if codec_threads is not None and "threads" not in dict(encoder.options):
        encoder = replace(encoder, options=(*encoder.options, ("threads", str(codec_threads))))
    encoder.check()
    paths = _check_outputs(source, [item.path for item in outputs])
    current = SharedInput(open_input(source, reconnect.timeout_s, reconnect.timeout_s))
    can_drop = drops(source, current.container)
    if can_drop and reconnect.attempts > 0:
        check_segment_names(paths)
    report = VideoReport()
    started = time.perf_counter()
    try:
        _unwarp_segments(
            current, table, source, outputs, paths, can_drop, encoder, selection, audio, sampling, interpolation,
            fixed_point, stop, progress, warn, memory_limit, reconnect, codec_threads, report,
        )  # fmt: skip
    finally:
        report.seconds = time.perf_counter() - started
    return report


def _unwarp_segments(
    current: SharedInput,
    table: PanoMappingTable,
    source: str,
    outputs: Sequence[ViewOutput],
    paths: list[Path],
    can_drop: bool,
    encoder: EncoderSettings,
    selection: Selection,
    audio: bool,
    sampling: str,
    interpolation: str,
    fixed_point: bool,
    stop: threading.Event,
    progress: Callable[[int, int | None], None] | None,
    warn: Callable[[str], None],
    memory_limit: int | None,
    reconnect: Reconnect,
    codec_threads: int | None,
    report: VideoReport,
) -> None:
    """The run of :func:`unwarp_video` from its opened input ``current`` on (its outputs ``paths`` checked): the
    input and the views checked, then one segment after another (a live input that drops reconnected) into
    ``report``. The input open at the end, or at an error, is closed."""
    live = is_live(source)
    try:
        size = _check_input(current.container, table, source)  # (first: it refuses an input with no video)
        declared_end = None if live else declared_duration_s(current.container)
        rate = frame_rate(current.container)
        in_format = current.container.streams.video[0].codec_context.pix_fmt or "yuv420p"
        work = work_format(in_format, encoder.pix_fmt)
        sizes = [item.view.output_size(table) for item in outputs]
        for view_size in sizes:
            check_output_size(work, view_size)
        check_memory(sizes, memory_limit)
        remappers = _LazyRemappers(table, outputs, size, work, sampling, interpolation, fixed_point)
        state = ReadState()
        segments = _Segments(report, source, warn, state, time.monotonic())
        while True:
            try:
                written = _write_segment(
                    current,
                    [segment_path(path, segments.number) for path in paths],
                    sizes,
                    work,
                    remappers,
                    encoder,
                    selection,
                    audio,
                    stop,
                    progress,
                    warn,
                    report,
                    state,
                    reconnect.timeout_s if can_drop else None,
                    segments.on_first_frame,
                    codec_threads,
                )
            except PanomapError as exc:
                if exc.source is not None:
                    raise
                raise PanomapError(exc.detail, source) from None  # (a frame of the input: name it)
            current.close()
            if not segments.ended(written, stop.is_set(), reconnect.attempts > 0):
                break
            opened = _reopen(source, table, size, reconnect, segments.gap, stop)
            if opened is None:
                segments.gave_up(stop.is_set())
                break
            current = SharedInput(opened)
        _say_what_came(report, source, selection, state, stop.is_set(), declared_end, rate, warn)
    finally:
        current.close()  # (on an abort while the reader still waits in a read: once it returns)


def _say_what_came(
    report: VideoReport,
    source: str,
    selection: Selection,
    state: ReadState,
    stopped: bool,
    declared_end: float | None,
    rate: float,
    warn: Callable[[str], None],
) -> None:
    """Where a run wrote nothing: an interrupted run if a stop came first (nothing wrong with the input), else
    an error saying why. Where a file's frames stopped well before the end its header declares (``declared_end``,
    None for a live input): one line through ``warn``, kept in ``report.problems``."""
    if report.frames_written == 0:
        if stopped:
            report.interrupted = True
            return
        raise PanomapError(_nothing_written(report, source, selection, declared_end), source)
    if state.at_end and not stopped and not report.problems:
        note = ended_early(declared_end, rate, state)
        if note is not None:
            report.problems.append(f"{source}: {note}")
            warn(report.problems[-1])


def _check_outputs(source: str, paths: list[Path]) -> list[Path]:
    """``paths``, refused before any work where two are one file, one is the input, or one cannot be made."""
    if len(set(paths)) != len(paths):
        raise PanomapError("two views would write the same file: put {name} in the output pattern")
    check_output_paths(
        [("the input", local_file(source))],
        [(f"the output of view {k + 1}", path) for k, path in enumerate(paths)],
    )
    for path in paths:
        container_format(path)
        folder = path.parent if str(path.parent) else Path(".")
        if not folder.is_dir():
            raise PanomapError("its folder does not exist", path)
        if not os.access(folder, os.W_OK | os.X_OK):
            raise PanomapError("its folder is not writable", path)
    return paths


class _LazyRemappers:
    """Every view's remapper, made on the first call (while the first frames decode: a few tenths of a
    second saved at start-up) and kept."""

    def __init__(
        self,
        table: PanoMappingTable,
        outputs: Sequence[ViewOutput],
        size: tuple[int, int],
        work: str,
        sampling: str,
        interpolation: str,
        fixed_point: bool,
    ) -> None:
        self.table, self.outputs, self.size, self.work = table, outputs, size, work
        self.sampling, self.interpolation, self.fixed_point = sampling, interpolation, fixed_point
        self.remappers: list[FrameRemapper] = []

    def __call__(self) -> list[FrameRemapper]:
        if not self.remappers:
            maps = []
            for item in self.outputs:
                try:
                    maps.append(build_map(self.table, item.view, self.sampling))
                except PanomapError as exc:  # (the view's problem: named by its output)
                    raise exc if exc.source is not None else PanomapError(exc.detail, item.path) from None
            self.remappers.extend(
                FrameRemapper(map_uv, self.size, self.work, self.interpolation, self.fixed_point) for map_uv in maps
            )
        return self.remappers


@dataclass
class _Segments:
    """The segments of a run and the gaps between them: which segment comes next, and the drop being
    reconnected (until a frame comes)."""

    report: VideoReport
    source: str
    warn: Callable[[str], None]
    state: ReadState
    started_at: float  # time.monotonic() when the run started
    number: int = 0
    gap: _OpenGap | None = None

    def on_first_frame(self) -> None:
        """The first frame of a connection: the gap before it (if any) ends, resumed."""
        if self.gap is None:
            return
        assert self.state.first_frame_at is not None and self.state.last_frame_at is not None
        closed = self.gap.close(self.state.first_frame_at, "resumed", self.number)
        self.report.gaps.append(closed)
        self.warn(closed.describe(self.source))
        self.gap = None

    def ended(self, written: bool, stopped: bool, reconnecting: bool) -> bool:
        """A connection ended (``written``: its segment got frames); True where the run goes on (a drop, to
        reconnect), False where it ends (the input's end, a stop, or a drop with reconnecting off)."""
        if written:
            self.report.segments += 1
            self.number += 1
        dropped = self.state.dropped
        if dropped is None or stopped:
            if dropped is not None:  # the drop was seen, then the stop came (it ended the run, not the input)
                self.report.interrupted = True
            if self.gap is None and dropped is not None:
                self.gap = self._open(dropped)
            if self.gap is not None:  # stopped while reconnecting, or after a reconnect before its first frame
                self.report.gaps.append(self.gap.close(time.monotonic(), "stopped"))
            return False
        if self.gap is None:
            self.gap = self._open(dropped)
        if not reconnecting:
            self.report.gaps.append(self.gap.close(time.monotonic(), "not reconnecting"))
            return False
        return True

    def gave_up(self, stopped: bool) -> None:
        """Reconnecting ended without a connection: every attempt failed, or a stop came."""
        assert self.gap is not None
        self.report.interrupted = stopped
        self.report.gaps.append(self.gap.close(time.monotonic(), "stopped" if stopped else "gave up"))

    def _open(self, reason: str) -> _OpenGap:
        return _OpenGap(reason, self.report.frames_written, self.state.last_frame_at, self.started_at)


class _NothingWritten(Exception):
    """A segment got no frame: its files are removed (all_or_none)."""


def _nothing_written(report: VideoReport, source: str, selection: Selection, declared_end: float | None) -> str:
    """Why a run wrote no frame, in words: a start past the clip's end, a drop, or frames that do not decode."""
    if selection.start_s > 0 and declared_end is not None and selection.start_s >= declared_end:
        clip = f"the clip lasts {declared_end:.2f} s"
        return f"--start {selection.start_s:g} s is past the end of the input: {clip} (nothing written)"
    why = f" ({report.gaps[-1].describe(source)})" if report.gaps else ""
    return f"no frame could be decoded (nothing written){why}"


def _check_input(container: Any, table: PanoMappingTable, source: str) -> tuple[int, int]:
    """The video's frame size (W, H), refused unless it is the table's image size."""
    stream = container.streams.video[0]
    size = frame_size(stream, source)
    if table.image_size is not None and size != tuple(table.image_size):
        raise PanomapError(
            f"its frames are {size[0]} x {size[1]}, the table is for "
            f"{table.image_size[0]} x {table.image_size[1]} images",
            source,
        )
    return size


def _write_segment(
    current: SharedInput,
    paths: list[Path],
    sizes: list[tuple[int, int]],
    work: str,
    build_remappers: Callable[[], list[FrameRemapper]],
    encoder: EncoderSettings,
    selection: Selection,
    audio: bool,
    stop: threading.Event,
    progress: Callable[[int, int | None], None] | None,
    warn: Callable[[str], None],
    report: VideoReport,
    state: ReadState,
    drop_timeout_s: float | None,
    on_first_frame: Callable[[], None],
    decoder_threads: int | None = None,
) -> bool:
    """Read one connection of the input into one file per view; True if any frame was written.

    The files are renamed into place together when the connection ends, or all
    removed if a writer fails (PanomapError) or no frame came (False).
    """
    container = current.container
    stream = container.streams.video[0]
    stream.thread_type = "AUTO"
    if decoder_threads is not None:
        stream.codec_context.thread_count = decoder_threads
    audio_stream = container.streams.audio[0] if audio and container.streams.audio else None
    report.audio = report.audio or audio_stream is not None
    rate = stream.average_rate or stream.guessed_rate
    if rate is not None and selection.every > 1:
        rate = Fraction(rate) / selection.every
    time_base = stream.time_base or Fraction(1, 90000)
    before = report.frames_written
    try:
        with contextlib.ExitStack() as files:
            files.enter_context(all_or_none())  # every output renamed into place at the end, or none
            writers: list[Writer] = []
            try:
                for path, view_size in zip(paths, sizes, strict=True):
                    temporary = files.enter_context(atomic_path(path))
                    writers.append(open_writer(path, temporary, view_size, rate, time_base, encoder, audio_stream))
                with opencv_threads(REMAP_THREADS):
                    _run(
                        current,
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
                        state,
                        drop_timeout_s,
                        on_first_frame,
                    )
            finally:
                for writer in writers:
                    writer.close()
            failed = next((writer for writer in writers if writer.error is not None), None)
            if failed is not None:  # (the old file of that name is kept; the partial one removed)
                raise PanomapError(f"writing failed ({reason(failed.error)})", failed.path)  # type: ignore[arg-type]
            if report.frames_written == before:
                raise _NothingWritten
    except _NothingWritten:
        return False
    report.outputs.extend(paths)
    return True


@dataclass
class _OpenGap:
    """A drop being reconnected: what is known before it ends."""

    reason: str
    frames_before: int
    last_frame_at: float | None  # time.monotonic() of the last frame before it (None: no frame yet)
    run_started_at: float  # time.monotonic() when the run started
    attempts: int = 0
    last_failure: str | None = None
    dropped_at: float = 0.0

    def __post_init__(self) -> None:
        self.dropped_at = time.monotonic()

    def close(self, end: float, outcome: GapOutcome, segment: int | None = None) -> Gap:
        """The gap as it ended at ``end`` (time.monotonic())."""
        begin = self.last_frame_at if self.last_frame_at is not None else self.dropped_at
        return Gap(
            self.reason,
            self.frames_before,
            begin - self.run_started_at,
            end - begin,
            self.attempts,
            outcome,
            segment,
            self.last_failure,
        )


def _reopen(
    source: str,
    table: PanoMappingTable,
    size: tuple[int, int],
    reconnect: Reconnect,
    gap: _OpenGap | None,
    stop: threading.Event,
) -> Any | None:
    """Open ``source`` again, waiting before each attempt (backoff); None when attempts run out or on ``stop``.

    A stream that comes back with frames of another size ends the run (PanomapError).
    """
    assert gap is not None
    while gap.attempts < reconnect.attempts:
        if stop.wait(reconnect.wait_s(gap.attempts + 1)):
            return None
        gap.attempts += 1
        try:
            container = open_input(source, reconnect.timeout_s, reconnect.timeout_s)
        except PanomapError as exc:
            gap.last_failure = exc.detail
            continue
        try:
            if _check_input(container, table, source) != size:
                raise PanomapError("its frame size changed when it reconnected", source)
        except BaseException:
            container.close()
            raise
        return container
    return None


# Memory a run takes per pixel of its views (bytes): the map, the remap's maps, the queued
# output frames and the encoder's own frames. Measured as peak RSS over output pixels: 98 for
# two 4000 x 3000 views (libx264 veryfast, 2 cores), 55 for three 7000 x 7000 on a larger machine.
BYTES_PER_VIEW_PIXEL = 100


def machine_memory() -> int | None:
    """The machine's physical memory (bytes), None where the system does not say."""
    try:
        return int(os.sysconf("SC_PHYS_PAGES")) * int(os.sysconf("SC_PAGE_SIZE"))
    except (ValueError, OSError, AttributeError):
        return None


def check_memory(sizes: Sequence[tuple[int, int]], memory_limit: int | None = None) -> int:
    """The estimated memory (bytes) of views of ``sizes`` (W, H); PanomapError beyond ``memory_limit``.

    ``memory_limit`` defaults to 3/4 of :func:`machine_memory` (no limit where unknown).
    """
    pixels = sum(width * height for width, height in sizes)
    needed = pixels * BYTES_PER_VIEW_PIXEL
    if memory_limit is None:
        total = machine_memory()
        memory_limit = None if total is None else total * 3 // 4
    if memory_limit is not None and needed > memory_limit:
        raise PanomapError(
            f"the views need about {_amount(needed)} of memory ({len(sizes)} view(s), {pixels:,} pixels "
            f"in all), more than the {_amount(memory_limit)} available (3/4 of this machine's): "
            "make the views smaller or run fewer at once"
        )
    return needed


def _amount(size: int) -> str:
    return f"{size / 1e9:.1f} GB" if size >= 1e9 else f"{size / 1e6:.1f} MB"


def _run(
    current: SharedInput,
    stream: Any,
    audio_stream: Any | None,
    work: str,
    build_remappers: Callable[[], list[FrameRemapper]],
    writers: list[Writer],
    selection: Selection,
    stop: threading.Event,
    progress: Callable[[int, int | None], None] | None,
    warn: Callable[[str], None],
    report: VideoReport,
    state: ReadState,
    drop_timeout_s: float | None,
    on_first_frame: Callable[[], None],
) -> None:
    """Run reader, remapping (here) and writers until the input ends, ``stop`` is set or a writer fails.

    An exception here (KeyboardInterrupt: an abort) ends the writers without
    flushing (their files are discarded) and leaves the input to its reader
    (:class:`SharedInput`) instead of waiting for a read that may never return.
    """
    container = current.container
    frames: queue.Queue[Any] = queue.Queue(QUEUE_FRAMES)
    halt = threading.Event()  # stop, a writer's failure, or the end of the run
    expected = expected_frames(stream, selection, is_live(str(container.name)))
    for writer in writers:
        writer.thread = threading.Thread(
            target=writer.run, args=(halt,), name=f"panomap-write-{writer.path.name}", daemon=True
        )
        writer.thread.start()

    def halted() -> bool:
        return halt.is_set() or stop.is_set()

    def on_audio(packet: Any) -> None:
        for writer in writers:
            put(writer.inbox, copy_packet(packet), halted)

    def read() -> None:
        try:
            read_frames(
                container,
                stream,
                audio_stream,
                work,
                selection,
                frames,
                halted,
                on_audio,
                warn,
                report,
                state,
                drop_timeout_s=drop_timeout_s,
            )
        finally:
            current.release()

    reader = threading.Thread(target=read, name="panomap-read", daemon=True)
    current.hold()
    try:
        reader.start()
    except BaseException:
        current.release()
        raise
    failure: BaseException | None = None
    try:
        remappers = build_remappers()
        first = True
        while not halted():
            try:
                frame = frames.get(timeout=0.1)
            except queue.Empty:
                continue
            if frame is END:
                break
            if first:
                on_first_frame()
                first = False
            for remapper, writer in zip(remappers, writers, strict=True):
                put(writer.inbox, remapper(frame), lambda w=writer: w.error is not None)  # type: ignore[misc]
            report.frames_written += 1
            if progress is not None:
                progress(report.frames_written, expected)
    except BaseException as exc:
        failure = exc
        raise
    finally:
        report.interrupted = stop.is_set() and all(writer.error is None for writer in writers)
        halt.set()
        _end_threads(reader, frames, writers, failure)


def _end_threads(
    reader: threading.Thread, frames: queue.Queue[Any], writers: list[Writer], failure: BaseException | None
) -> None:
    """Wait for the reader to see the halt, then let every writer finish its file.

    After a ``failure`` the writers stop after the frame they are on, without
    flushing (their files are discarded). After an abort (a KeyboardInterrupt,
    also one while waiting here) the reader is not waited for either: it may
    wait in a read that never returns, and the input is left to it
    (:class:`SharedInput`). Either way no writer thread is left inside its container.
    """
    abandon = failure is not None
    try:
        if isinstance(failure, Exception | None):
            while reader.is_alive():  # let the reader see the halt, even if it waits on a full queue
                with contextlib.suppress(queue.Empty):
                    frames.get(timeout=0.1)
        if not abandon:
            for writer in writers:
                put(writer.inbox, END, lambda w=writer: w.error is not None)  # type: ignore[misc]
    except BaseException:
        abandon = True
        raise
    finally:
        try:
            _join_writers(writers, abandon)
        except BaseException:  # (interrupted while a writer flushes: abandon them all)
            _join_writers(writers, True)
            raise


def _join_writers(writers: list[Writer], abandon: bool) -> None:
    for writer in writers:
        if abandon:
            writer.abandon()
    for writer in writers:
        if writer.thread is not None:
            writer.thread.join()
