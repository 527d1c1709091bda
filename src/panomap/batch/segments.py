"""Long videos in time segments: unwarped one by one (anywhere), then joined without re-encoding.

A video of duration T split every S seconds gives ``ceil(T / S)`` segments: segment k reads
the input from ``k S`` (decoding from the keyframe before it, as ``ffmpeg -ss`` does, and
dropping the frames before ``k S``) for S seconds, the last to the end. Every frame belongs
to exactly one segment. Each segment's output starts its timestamps at 0 (the ``start``
offset subtracted, see :mod:`panomap.video.source`); the join adds the same offset back,
packet by packet (stream copy: PyAV remux), so the joined output has the input's
timestamps, as an unsegmented run gives.

Convention: times in seconds; ``offset`` is exactly the number of input time-base ticks
that the segment's run subtracted, as a :class:`~fractions.Fraction` of seconds.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path
from typing import Any

import av

from ..errors import PanomapError
from ..files import atomic_path
from ..video.output import container_format
from ..video.source import open_input


@dataclass(frozen=True)
class Probe:
    """What the driver learns of a video before planning it."""

    duration_s: float | None
    frames: int | None
    start_s: float
    time_base: Fraction
    rate: Fraction | None


@dataclass(frozen=True)
class Segment:
    """Part ``index`` of a video: ``start_s`` for ``duration_s`` (None: to the end)."""

    index: int
    start_s: float
    duration_s: float | None
    offset: Fraction


def probe(path: Path) -> Probe:
    """Duration, frame count, start time, time base and rate of ``path``'s first video stream."""
    container = open_input(str(path))
    try:
        stream = container.streams.video[0]
        time_base = Fraction(stream.time_base or Fraction(1, 90000))
        rate = stream.average_rate or stream.guessed_rate
        start = float(stream.start_time * time_base) if stream.start_time is not None else 0.0
        duration: float | None = None
        if stream.duration:
            duration = float(stream.duration * time_base)
        elif container.duration:
            duration = container.duration / av.time_base
        frames = stream.frames or (round(duration * float(rate)) if duration and rate else None)
        return Probe(duration, frames or None, start, time_base, Fraction(rate) if rate else None)
    finally:
        container.close()


def plan_segments(info: Probe, segment_s: float) -> list[Segment]:
    """The segments of a video of ``info`` every ``segment_s`` seconds (one when it is shorter).

    The count is taken from the last frame's time (duration less one frame), so that the last
    segment is never empty; at a constant frame rate a segment holds a whole number of frames,
    one at least (a segment shorter than a frame would hold none).
    """
    if not (math.isfinite(segment_s) and segment_s > 0):
        raise PanomapError(f"the segment length must be more than 0 s, not {segment_s:g}")
    if info.duration_s is None:
        return [Segment(0, 0.0, None, Fraction(0))]
    if info.rate:
        frame_s = 1 / float(info.rate)
        segment_s = max(1, round(segment_s / frame_s)) * frame_s
    last_frame = info.duration_s - (1 / float(info.rate) if info.rate else 0.0)
    count = max(1, math.ceil(last_frame / segment_s - 1e-9))
    segments = []
    for index in range(count):
        start = index * segment_s
        ticks = round((info.start_s + start) / float(info.time_base)) if index else 0
        duration = segment_s if index < count - 1 else None
        segments.append(Segment(index, start, duration, ticks * info.time_base))
    return segments


def join_segments(parts: Sequence[tuple[Path, Fraction]], output: Path) -> int:
    """Join segment files (each with its offset in seconds) into ``output``, stream copy; the frame count.

    Every stream of the first part (video, and audio where there is some) is copied; packets
    get their offset added, in their own stream's time base. ``output`` appears atomically.
    """
    frames = 0
    with atomic_path(output) as temporary:
        with av.open(str(temporary), "w", format=container_format(output)) as joined:
            streams: list[Any] = []
            last_dts: dict[int, int] = {}
            for number, (part, offset) in enumerate(parts):
                with av.open(str(part)) as source:
                    kept = [s for s in source.streams if s.type in ("video", "audio")]
                    if number == 0:
                        for stream in kept:
                            made = joined.add_stream_from_template(stream)
                            made.time_base = stream.time_base
                            streams.append(made)
                    if len(kept) != len(streams) or any(a.type != b.type for a, b in zip(kept, streams, strict=False)):
                        raise PanomapError(f"segment {number} holds other streams than the first", output)
                    for packet in source.demux(kept):
                        if packet.size == 0 or packet.dts is None:
                            continue
                        position = kept.index(packet.stream)
                        ticks = round(offset / packet.time_base)
                        packet.pts = None if packet.pts is None else packet.pts + ticks
                        packet.dts += ticks
                        if packet.dts <= last_dts.get(position, packet.dts - 1):
                            raise PanomapError(
                                f"segment {number} overlaps the one before it (timestamps going back)", output
                            )
                        last_dts[position] = packet.dts
                        if packet.stream.type == "video":
                            frames += 1
                        packet.stream = streams[position]
                        joined.mux(packet)
    return frames
