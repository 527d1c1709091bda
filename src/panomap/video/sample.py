"""Frames taken apart in time from a video file: the pictures ``panomap fit --video`` learns a camera from."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import av

from ..errors import PanomapError
from ..files import input_file
from .source import declared_duration_s, first_frame, frame_rate


def frame_times(duration_s: float, count: int) -> list[float]:
    """``count`` times (s from the start) evenly spread over ``duration_s``: the middle of each of ``count``
    equal spans, so that neither the first nor the last frame, often a fade, is taken."""
    return [duration_s * (k + 0.5) / count for k in range(count)]


def sample_frames(path: str | Path, count: int, max_pixels: int) -> list[tuple[float, Any]]:
    """``count`` frames of the video at ``path``, each an 8-bit BGR image (H, W, 3) with its time (s), at
    :func:`frame_times` over its declared duration (:func:`each_frame`, all held).

    Raises
    ------
    PanomapError
        Naming the file, where it is not a video PyAV decodes, its header gives no duration, or its frames are
        larger than ``max_pixels``.
    """
    frames = list(each_frame(path, count, max_pixels))
    if not frames:
        raise PanomapError("no frame of it could be decoded", path)
    return frames


def frame_size(path: str | Path) -> tuple[int, int]:
    """(width, height) of the frames of the video at ``path``, from its stream's header, nothing decoded.

    Raises
    ------
    PanomapError
        Naming the file, where it is not a video PyAV opens, or has no video stream or no frame size.
    """
    input_file(path)  # (a FIFO would block the open; a missing file is no "video panomap cannot decode")
    try:
        with av.open(str(path)) as container:
            if not container.streams.video:
                raise PanomapError("has no video stream", path)
            codec = container.streams.video[0].codec_context
            width, height = int(codec.width), int(codec.height)
    except (av.error.FFmpegError, OSError, ValueError):
        raise PanomapError("is not a video panomap can decode", path) from None
    if width <= 0 or height <= 0:
        raise PanomapError("its header gives no frame size", path)
    return width, height


def each_frame(path: str | Path, count: int, max_pixels: int) -> Iterator[tuple[float, Any]]:
    """The frames of :func:`sample_frames`, decoded one at a time, as they are asked for: a caller that keeps
    few of them holds few (``panomap fit --video`` drops those that show a view already seen).

    Raises
    ------
    PanomapError
        As :func:`sample_frames` (the header's problems before any frame is decoded).
    """
    input_file(path)
    try:
        with av.open(str(path)) as container:
            streams = len(container.streams.video)
            formats = container.format.name.split(",")
            duration = declared_duration_s(container) if streams else None
            rate = frame_rate(container) if streams else 0.0
    except (av.error.FFmpegError, OSError, ValueError):
        raise PanomapError("is not a video panomap can decode", path) from None
    if not streams:
        raise PanomapError("has no video stream", path)
    if any(name.startswith("image") or name.endswith("_pipe") for name in formats):
        raise PanomapError("is a picture, not a video: give it as a picture", path)
    if duration is None or not duration > 0:
        raise PanomapError("its header gives no duration: give its frames as pictures, each at its time", path)
    # The spans cover the frames' start times: the last frame starts one frame before the declared end.
    for at_s in frame_times(max(duration - 1.0 / rate, 0.0), count):
        try:
            frame = first_frame(path, max_pixels, at_s)
        except PanomapError as exc:
            if "larger than panomap reads" in exc.detail:
                raise
            continue  # a frame the file declares but does not hold (a cut-short file): the others serve
        if frame is not None:
            yield at_s, frame
