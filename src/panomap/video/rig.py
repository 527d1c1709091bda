"""A rig's video: one view of a rig, blended from one video holding every camera's picture, or one per camera.

The pipeline is :mod:`.unwarp`'s, with one reader per input::

    reader per input (demux + threaded decode)  --frames-->  blend (this thread)  --frames-->  writer(s)

- **Inputs.** A rig whose pictures share one frame (a dual-fisheye camera's raw video: the rig's ``offsets``)
  takes that one video; any other rig one video per camera, in the rig's order, read in step: the run stops at
  the shortest. Every input is checked (it opens, holds video of its camera's size, or of the frame's) before
  any work. Timestamps, the frame rate and the audio are the first input's.
- **Frames** are blended plane by plane in the decoder's YUV format (as :mod:`.frames`: each chroma plane with
  the maps and weights sampled at its sample centres) by :class:`panomap.rig.fast.RigPlane`: one remap of the
  whole output, the overlap band blended apart; or once in BGR where the output is RGB.
- **Gains** are found once, on the first frame, and kept: the picture does not flicker. In YUV one gain per
  camera, from the luma over the overlaps (an exposure difference), scales luma from black (16, or 0 in full
  range) and chroma from grey (128); in BGR one per channel, as the still commands find them.
"""

from __future__ import annotations

import contextlib
import queue
import threading
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, replace
from fractions import Fraction
from pathlib import Path
from typing import Any

import av
import cv2
import numpy as np
from numpy.typing import NDArray

from ..errors import PanomapError
from ..files import all_or_none, atomic_path, check_output_paths, local_file
from ..rig import CameraRig, camera_maps
from ..rig.blend import WRAPPING_KINDS
from ..rig.fast import RigPlane
from ..rig.seams import seam_weights, video_seam_step
from ..views import View
from .frames import BGR, PLANAR_FORMATS, REMAP_THREADS, _chroma_map, _plane_array, check_output_size, opencv_threads
from .frames import work_format as choose_work_format
from .handoff import END, QUEUE_FRAMES, put, reason
from .output import EncoderSettings, Writer, open_writer
from .report import VideoReport
from .source import (
    ReadState,
    Selection,
    SharedInput,
    copy_packet,
    expected_frames,
    frame_size,
    open_input,
    read_frames,
)
from .unwarp import _check_outputs, check_memory

# Luma's black level per planar format (gains scale from it); chroma's grey is 128.
FULL_RANGE = ("yuvj420p", "yuvj422p", "yuvj444p", "gray")


def rig_inputs(rig: CameraRig) -> list[tuple[str, tuple[int, int]]]:
    """What the rig's video takes: (what it is, (width, height)) per input."""
    if rig.offsets is not None:
        assert rig.frame_size is not None
        return [("the rig's frame", rig.frame_size)]
    return [(f"camera {name}", table.image_size) for name, table in zip(rig.names, rig.tables, strict=True)]  # type: ignore[misc]


def check_rig_sources(rig: CameraRig, sources: Sequence[str]) -> None:
    """Refuse a wrong number of inputs for ``rig`` (one frame holding them all, or one per camera)."""
    wanted = rig_inputs(rig)
    if len(sources) != len(wanted):
        if rig.offsets is not None:
            raise PanomapError(
                f"the rig's {rig.count} cameras share one frame: give that one video, not {len(sources)}"
            )
        raise PanomapError(
            f"give one video per camera of the rig, in its order ({', '.join(rig.names)}), not {len(sources)}"
        )


class RigFrameRemapper:
    """One view of a rig for decoded frames of one pixel format: each plane's :class:`RigPlane`.

    The luma's plane is built here while the chroma's are built on a helper thread (OpenCV and NumPy let go of
    the GIL), which then blends the luma of every frame.

    Parameters
    ----------
    rig : CameraRig
    maps : list of (H, W, 2) float32
        Each camera's map in its own picture (:func:`panomap.rig.camera_maps`); taken over: where the rig's
        pictures share one frame, each camera's offset is added to its map in place.
    work_format : str
        A planar format of :data:`.frames.PLANAR_FORMATS`, or ``bgr24``.
    interpolation : {"linear", "nearest"}
    wrap : bool
        The view's columns wrap around (its weights feather across the wrap).
    """

    def __init__(
        self,
        rig: CameraRig,
        maps: Sequence[NDArray[np.float32]],
        work_format: str,
        interpolation: str = "linear",
        wrap: bool = False,
    ) -> None:
        self.work_format = work_format
        self.gains: NDArray[np.float64] | None = None
        self._helper = ThreadPoolExecutor(1, thread_name_prefix="panomap-blend")
        height, width = maps[0].shape[:2]
        self.output_size = (width, height)
        inputs = [size for _, size in rig_inputs(rig)]
        reads = list(range(rig.count))
        if rig.offsets is not None:
            for map_uv, offset in zip(maps, rig.offsets, strict=True):
                for axis, shift in enumerate(offset):
                    if shift:  # (u or v alone, in place: a 2-vector added across the map took 10 x longer)
                        map_uv[..., axis] += np.float32(shift)
            reads = [0] * rig.count
        seams = seam_weights(maps, wrap, step=video_seam_step((height, width)))
        if work_format == BGR:
            self.planes = [RigPlane(maps, seams, inputs, reads, 3, interpolation)]
            return
        check_output_size(work_format, self.output_size)
        sub_x, sub_y, fills = PLANAR_FORMATS[work_format]

        def chroma_planes() -> list[RigPlane]:
            chroma = [_chroma_map(m, sub_x, sub_y) for m in maps]
            sizes = [(-(-w >> sub_x), -(-h >> sub_y)) for w, h in inputs]
            first = RigPlane(chroma, seams.subsampled(chroma, sub_x, sub_y), sizes, reads, 1, interpolation, fills[1],
                             128.0)  # fmt: skip
            return [first, *(first.twin(fill) for fill in fills[2:])]

        chroma = self._helper.submit(chroma_planes) if len(fills) > 1 else None
        black = 0.0 if work_format in FULL_RANGE else 16.0
        self.planes = [RigPlane(maps, seams, inputs, reads, 1, interpolation, fills[0], black)]
        if chroma is not None:
            self.planes += chroma.result()

    def close(self) -> None:
        """End the helper thread."""
        self._helper.shutdown()

    def __call__(self, frames: Sequence[Any]) -> Any:
        """Blend one decoded frame per input (already in the work format); a new frame out. The gains are found
        on the first call and kept."""
        width, height = self.output_size
        if self.work_format == BGR:
            plane = self.planes[0]
            plane.load([frame.to_ndarray(format=BGR) for frame in frames])
            if self.gains is None:
                self.gains = plane.band_gains()
                plane.set_gains(self.gains)
            out = av.VideoFrame.from_ndarray(plane(), format=BGR)
        else:
            for index, plane in enumerate(self.planes):
                plane.load([_plane_array(frame.planes[index]) for frame in frames])
            if self.gains is None:
                self.gains = self.planes[0].band_gains()  # (k, 1): the luma's
                for plane in self.planes:
                    plane.set_gains(self.gains)
            out = av.VideoFrame(width, height, self.work_format)
            targets = [_plane_array(target) for target in out.planes]
            # The luma on a second thread, the chroma here (OpenCV and NumPy let go of the GIL).
            luma = self._helper.submit(self.planes[0], targets[0])
            for plane, target in zip(self.planes[1:], targets[1:], strict=True):
                plane(out=target)
            luma.result()
        out.pts = frames[0].pts
        if frames[0].time_base is not None:
            out.time_base = frames[0].time_base
        return out


@dataclass
class _Input:
    """One input of the run: its container, its stream, the queue its reader fills."""

    source: str
    shared: SharedInput
    stream: Any
    frames: queue.Queue[Any]
    report: VideoReport
    thread: threading.Thread | None = None


def unwarp_rig_video(
    rig: CameraRig,
    sources: Sequence[str],
    output: Path,
    view: View,
    *,
    encoder: EncoderSettings = EncoderSettings(),
    selection: Selection = Selection(),
    audio: bool = True,
    sampling: str = "bilinear",
    interpolation: str = "linear",
    stop: threading.Event | None = None,
    progress: Callable[[int, int | None], None] | None = None,
    warn: Callable[[str], None] | None = None,
    memory_limit: int | None = None,
    codec_threads: int | None = None,
    timeout_s: float = 10.0,
) -> VideoReport:
    """Blend the rig's view of ``sources`` into the video ``output``; returns what was done.

    As :func:`.unwarp.unwarp_video` for one view, with a rig: ``sources`` is one video holding every camera's
    picture (a rig with ``offsets``) or one per camera in the rig's order, read in step until the shortest
    ends. Everything that can be checked is checked before the first frame is read (the number of inputs, each
    input's frame size, the encoder, the output); the maps are built while the first frames decode, and a view
    the rig cannot see ends the run with no output. A live input that drops ends the run (no reconnecting: the
    cameras' streams would fall out of step), the frames before it kept.

    Parameters
    ----------
    rig : CameraRig
    sources : sequence of str
        One video (the rig's frame), or one per camera.
    output : Path
        The blended view's video.
    view : View
        The view (any kind; a panorama's weights wrap around).
    encoder, selection, audio, sampling, stop, progress, warn, memory_limit, codec_threads
        As :func:`.unwarp.unwarp_video` (audio: the first input's).
    interpolation : {"linear", "nearest"}
        How each frame is read between its pixels (the fast blend's clamp is exact for these two).
    timeout_s : float
        How long opening and each read of a network input may wait (s).

    Returns
    -------
    VideoReport
    """
    stop = stop or threading.Event()
    warn = warn or (lambda message: None)
    if interpolation not in ("linear", "nearest"):
        raise PanomapError(f"a rig's video reads linear or nearest, not {interpolation!r}")
    check_rig_sources(rig, sources)
    if codec_threads is not None and "threads" not in dict(encoder.options):
        encoder = replace(encoder, options=(*encoder.options, ("threads", str(codec_threads))))
    encoder.check()
    _check_outputs(sources[0], [output])
    check_output_paths([(f"input {k + 1}", local_file(s)) for k, s in enumerate(sources)], [("the output", output)])
    report = VideoReport()
    started = time.perf_counter()
    inputs: list[_Input] = []
    try:
        for source, (what, size) in zip(sources, rig_inputs(rig), strict=True):
            container = open_input(source, timeout_s, timeout_s)
            shared = SharedInput(container)
            stream = container.streams.video[0]
            inputs.append(_Input(source, shared, stream, queue.Queue(QUEUE_FRAMES), VideoReport()))
            got = frame_size(stream, source)
            if got != tuple(size):
                raise PanomapError(f"its frames are {got[0]} x {got[1]}, {what} is {size[0]} x {size[1]}", source)
        in_format = inputs[0].stream.codec_context.pix_fmt or "yuv420p"
        work = choose_work_format(in_format, encoder.pix_fmt)
        view_size = view.output_size(rig.tables[0])
        check_output_size(work, view_size)
        check_memory([view_size] * (rig.count + 2), memory_limit)  # (the buffer, the band, each camera's map)
        _write(inputs, rig, output, view, view_size, work, encoder, selection, audio, sampling, interpolation, stop,
               progress, warn, report, codec_threads)  # fmt: skip
    finally:
        for item in inputs:
            item.shared.close()
        report.seconds = time.perf_counter() - started
    if report.frames_written == 0:
        if stop.is_set():
            report.interrupted = True
        else:
            raise PanomapError("no frame could be decoded (nothing written)", sources[0])
    return report


def _write(
    inputs: list[_Input],
    rig: CameraRig,
    output: Path,
    view: View,
    view_size: tuple[int, int],
    work: str,
    encoder: EncoderSettings,
    selection: Selection,
    audio: bool,
    sampling: str,
    interpolation: str,
    stop: threading.Event,
    progress: Callable[[int, int | None], None] | None,
    warn: Callable[[str], None],
    report: VideoReport,
    codec_threads: int | None,
) -> None:
    """Open the writer, run the readers and the blend; the output renamed into place when done, else removed."""
    first = inputs[0]
    container = first.shared.container
    for item in inputs:
        item.stream.thread_type = "AUTO"
        if codec_threads is not None:
            item.stream.codec_context.thread_count = codec_threads
    audio_stream = container.streams.audio[0] if audio and container.streams.audio else None
    report.audio = audio_stream is not None
    rate = first.stream.average_rate or first.stream.guessed_rate
    if rate is not None and selection.every > 1:
        rate = Fraction(rate) / selection.every
    time_base = first.stream.time_base or Fraction(1, 90000)
    try:
        with contextlib.ExitStack() as files:
            files.enter_context(all_or_none())  # (the output renamed into place at the end, or removed)
            temporary = files.enter_context(atomic_path(output))
            writer = open_writer(output, temporary, view_size, rate, time_base, encoder, audio_stream)
            try:
                with opencv_threads(REMAP_THREADS):
                    _run(inputs, rig, view, work, writer, selection, audio_stream, sampling, interpolation, stop,
                         progress, warn, report)  # fmt: skip
            finally:
                writer.close()
            if writer.error is not None:
                raise PanomapError(f"writing failed ({reason(writer.error)})", output)
            if report.frames_written == 0:
                raise _NothingWritten
    except _NothingWritten:
        return
    report.outputs.append(output)


class _NothingWritten(Exception):
    """No frame was written: the output is removed (all_or_none)."""


def _run(
    inputs: list[_Input],
    rig: CameraRig,
    view: View,
    work: str,
    writer: Writer,
    selection: Selection,
    audio_stream: Any | None,
    sampling: str,
    interpolation: str,
    stop: threading.Event,
    progress: Callable[[int, int | None], None] | None,
    warn: Callable[[str], None],
    report: VideoReport,
) -> None:
    """Readers, the blend (here) and the writer, until the shortest input ends, ``stop`` or a failure."""
    halt = threading.Event()
    expected_each = [expected_frames(item.stream, selection, False) for item in inputs]
    expected = None if any(e is None for e in expected_each) else min(expected_each)  # type: ignore[type-var]
    writer.thread = threading.Thread(target=writer.run, args=(halt,), name="panomap-write-rig", daemon=True)
    writer.thread.start()

    def halted() -> bool:
        return halt.is_set() or stop.is_set()

    def on_audio(packet: Any) -> None:
        put(writer.inbox, copy_packet(packet), halted)

    def reader(item: _Input, with_audio: Any | None) -> Callable[[], None]:
        def read() -> None:
            try:
                read_frames(item.shared.container, item.stream, with_audio, work, selection, item.frames, halted,
                            on_audio, warn, item.report, ReadState())  # fmt: skip
            finally:
                item.shared.release()

        return read

    for k, item in enumerate(inputs):
        item.shared.hold()
        item.thread = threading.Thread(target=reader(item, audio_stream if k == 0 else None),
                                       name=f"panomap-read-{k}", daemon=True)  # fmt: skip
        item.thread.start()
    failure: BaseException | None = None
    closing = contextlib.ExitStack()
    try:
        # The maps on every core, cameras side by side (the decoder waits once its first frames are queued); the
        # weights with OpenCV on one thread (its distance transform differs in its last bits with its threads),
        # the cameras' distance transforms side by side.
        with opencv_threads(cv2.getNumberOfCPUs()):
            maps = camera_maps(rig, view, sampling, threads=cv2.getNumberOfCPUs())
        blend = RigFrameRemapper(rig, maps, work, interpolation, wrap=view.kind in WRAPPING_KINDS)
        closing.callback(blend.close)
        while not halted():
            frames = []
            for item in inputs:
                frame = None
                while frame is None and not halted():
                    with contextlib.suppress(queue.Empty):
                        frame = item.frames.get(timeout=0.1)
                if frame is None or frame is END:
                    break
                frames.append(frame)
            if len(frames) < len(inputs):
                break
            put(writer.inbox, blend(frames), lambda: writer.error is not None)
            report.frames_written += 1
            if progress is not None:
                progress(report.frames_written, expected)
    except BaseException as exc:
        failure = exc
        raise
    finally:
        report.frames_read = inputs[0].report.frames_read
        report.frames_skipped = sum(item.report.frames_skipped for item in inputs)
        report.problems += [problem for item in inputs for problem in item.report.problems]
        report.interrupted = stop.is_set() and writer.error is None
        halt.set()
        closing.close()
        _end(inputs, writer, failure)


def _end(inputs: list[_Input], writer: Writer, failure: BaseException | None) -> None:
    """Let the readers see the halt, then the writer finish its file (or, after a failure, stop at once)."""
    abandon = failure is not None
    try:
        if isinstance(failure, Exception | None):
            for item in inputs:
                while item.thread is not None and item.thread.is_alive():
                    with contextlib.suppress(queue.Empty):
                        item.frames.get(timeout=0.1)
        if not abandon:
            put(writer.inbox, END, lambda: writer.error is not None)
    except BaseException:
        abandon = True
        raise
    finally:
        if abandon:
            writer.abandon()
        if writer.thread is not None:
            writer.thread.join()
