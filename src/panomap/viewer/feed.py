"""Frames decoded here for the page: a video the browser cannot play itself, or a live source.

One thread decodes the source (PyAV), paced at the source's rate for a file (as it would play) and as
fast as frames come for a live source, and keeps only the newest frame: the server's memory does not
grow with the length of the stream or the number of pages. A page gets it as JPEG, cut to the part its
view reads (:meth:`FrameFeed.jpeg`). Pages ask for "the frame after
the one I have" (:meth:`FrameFeed.frame_after`), so a slow page skips frames instead of queueing
them. The thread starts with the first request and ends when no page has asked for
``idle_stop_s`` seconds (a closed page frees it); a file then goes on where it was.

A file can be paused and sought (:meth:`FrameFeed.control`). A live source that drops (ends, fails,
or sends nothing for the reconnect timeout) is opened again with the backoff of
:class:`~panomap.video.live.Reconnect`, as ``panomap video`` does, and :meth:`FrameFeed.status`
says so for the page.
"""

from __future__ import annotations

import contextlib
import threading
import time
from dataclasses import dataclass
from typing import Any

import av
import cv2
import numpy as np
from numpy.typing import NDArray

from ..errors import PanomapError
from ..video.handoff import reason
from ..video.live import Reconnect
from ..video.source import drops, open_input
from .source import HeldFile, Source, open_held

JPEG_QUALITY = 85
# JPEG answers kept (the newest frame for a few pages' windows).
ENCODED_KEPT = 4
# A file's playback that falls this far (s) behind its clock restarts the clock instead of rushing.
MAX_LAG_S = 0.5


@dataclass(frozen=True)
class Frame:
    """One decoded frame as the page gets it.

    ``index`` counts frames over the feed's life (1, 2, ...); ``time_s`` is the frame's time in the
    source (s from a file's start; for a live source, from its first frame of this connection);
    ``decoded_at`` is ``time.monotonic()`` when it was decoded; ``image`` its picture, (H, W, 3) BGR,
    read-only.
    """

    index: int
    time_s: float
    decoded_at: float
    image: NDArray[np.uint8]


def window_of(size: tuple[int, int], window: tuple[int, int, int, int] | None) -> tuple[int, int, int, int]:
    """``window`` (x0, y0, width, height, px) clipped to an image of ``size``; the whole image for None or an
    empty window."""
    width, height = size
    if window is None:
        return 0, 0, width, height
    x0, y0, w, h = window
    x0, y0 = min(max(x0, 0), width - 1), min(max(y0, 0), height - 1)
    w, h = min(max(w, 1), width - x0), min(max(h, 1), height - y0)
    return x0, y0, w, h


@dataclass(frozen=True)
class FeedStatus:
    """What the feed is doing, for the page: ``state`` one of ``idle``, ``playing``, ``paused``,
    ``ended``, ``reconnecting``, ``failed``, with ``message`` (why, in words), the newest frame's time
    (s) and index."""

    state: str
    message: str
    time_s: float | None
    index: int
    paused: bool


class _Stop(Exception):
    """The decoding thread is to end (the feed closes, or no page asks any more)."""


class _Seek(Exception):
    """A seek was asked for: decoding starts again from there."""


class FrameFeed:
    """Decodes ``source`` (a video file or a live source) for the page, newest frame only.

    Parameters
    ----------
    source : Source
        A ``video`` or ``live`` source.
    reconnect : Reconnect
        How a live source that drops is opened again (its ``timeout_s`` also bounds each read).
    quality : int
        JPEG quality of the frames, 1-100.
    idle_stop_s : float
        The thread ends when no page has asked for a frame for this long (s).
    file : HeldFile or None
        A video file's :class:`~panomap.viewer.source.HeldFile`, decoded every time playback starts or seeks
        (whatever the name points to by then); None: the file is opened here, once, and closed by :meth:`close`.
    """

    def __init__(
        self,
        source: Source,
        reconnect: Reconnect | None = None,
        quality: int = JPEG_QUALITY,
        idle_stop_s: float = 10.0,
        file: HeldFile | None = None,
    ) -> None:
        if source.kind not in ("video", "live"):
            raise PanomapError(f"only a video or a live source has frames to feed, not {source.kind}", source.name)
        local = source.path is not None
        self._owned_file = HeldFile(source.name) if file is None and local else None
        self._file = file or self._owned_file
        self.source = source
        self.reconnect = reconnect or Reconnect()
        self.quality = int(quality)
        self.idle_stop_s = idle_stop_s
        self._changed = threading.Condition()
        self._frame: Frame | None = None
        self._encoded: dict[tuple[int, tuple[int, int, int, int]], bytes] = {}  # (index, window) -> JPEG, oldest first
        self._index = 0
        self._thread: threading.Thread | None = None
        self._asked_at = time.monotonic()
        self._closing = False
        self._paused = False
        self._seek_s: float | None = None
        self._position_s = 0.0  # where a file goes on from when the thread starts again
        self._connection = source.connection  # (the first reading's, opened by open_source)
        self._state = "idle"
        self._message = "waiting for a page to ask for frames"

    # ------------------------------------------------------------------ the page's side

    def frame_after(self, index: int, wait_s: float) -> Frame | None:
        """The newest frame if its index is above ``index``; otherwise wait up to ``wait_s`` (s) for one.

        None when no newer frame came in time (paused, ended, reconnecting, or a slow source).
        Starts the decoding thread where it is not running.
        """
        deadline = time.monotonic() + wait_s
        with self._changed:
            self._asked_at = time.monotonic()
            self._start()
            while not self._closing:
                if self._frame is not None and self._frame.index > index:
                    return self._frame
                left = deadline - time.monotonic()
                if left <= 0:
                    return None
                self._changed.wait(left)
        return None

    def control(self, paused: bool | None = None, seek_s: float | None = None) -> None:
        """Pause or play, and seek to ``seek_s`` (s from the start, clamped to the file); a file only."""
        if self.source.kind != "video":
            raise PanomapError("a live source cannot be paused or sought", self.source.name)
        with self._changed:
            if paused is not None:
                self._paused = paused
            if seek_s is not None:
                end = self.source.duration_s
                self._seek_s = max(0.0, seek_s if end is None else min(seek_s, end))
            self._asked_at = time.monotonic()
            self._start()
            self._changed.notify_all()

    def status(self) -> FeedStatus:
        with self._changed:
            frame = self._frame
            state = "paused" if self._paused and self._state == "playing" else self._state
            return FeedStatus(state, self._message, None if frame is None else frame.time_s, self._index, self._paused)

    @property
    def running(self) -> bool:
        """Whether the decoding thread is alive."""
        with self._changed:
            return self._thread is not None and self._thread.is_alive()

    def close(self, timeout_s: float = 5.0) -> None:
        """End the decoding thread (waits up to ``timeout_s`` for it: a live read may take its timeout)."""
        with self._changed:
            self._closing = True
            self._changed.notify_all()
            thread = self._thread
        if thread is not None:
            thread.join(timeout_s)
        if self._connection is not None:  # (never read)
            self._connection.close()
            self._connection = None
        if self._owned_file is not None:
            self._owned_file.close()

    # ------------------------------------------------------------------ the thread

    def _start(self) -> None:
        """Start the thread (holding the lock) unless it runs or the feed is closing."""
        if self._closing or (self._thread is not None and self._thread.is_alive()):
            return
        self._thread = threading.Thread(target=self._run, name="panomap-view-feed", daemon=True)
        self._thread.start()

    def _set(self, state: str, message: str) -> None:
        with self._changed:
            self._state, self._message = state, message
            self._changed.notify_all()

    def _check(self) -> None:
        """Raise :class:`_Stop` when the thread is to end, :class:`_Seek` when a seek waits (lock held)."""
        if self._closing or time.monotonic() - self._asked_at > self.idle_stop_s:
            raise _Stop
        if self._seek_s is not None:
            raise _Seek

    def _wait(self, seconds: float) -> None:
        """Sleep ``seconds`` unless the feed is stopped or sought meanwhile (then raise)."""
        deadline = time.monotonic() + seconds
        with self._changed:
            while True:
                self._check()
                left = deadline - time.monotonic()
                if left <= 0:
                    return
                self._changed.wait(min(left, 0.25))

    def jpeg(self, frame: Frame, window: tuple[int, int, int, int] | None = None) -> bytes:
        """``frame``'s picture within ``window`` (x0, y0, width, height, px; clipped; None: all of it) as JPEG.

        A page sends only the part of the frame its view reads. The last few answers are kept (pages that
        show the same view share them).
        """
        box = window_of(self.source.size, window)
        key = (frame.index, box)
        with self._changed:
            cached = self._encoded.get(key)
        if cached is not None:
            return cached
        x0, y0, w, h = box
        ok, encoded = cv2.imencode(
            ".jpg", frame.image[y0 : y0 + h, x0 : x0 + w], [cv2.IMWRITE_JPEG_QUALITY, self.quality]
        )
        if not ok:
            raise PanomapError("a frame could not be encoded as JPEG", self.source.name)
        data = encoded.tobytes()
        with self._changed:
            self._encoded[key] = data
            while len(self._encoded) > ENCODED_KEPT:
                self._encoded.pop(next(iter(self._encoded)))
        return data

    def _publish(self, image: Any, time_s: float) -> None:
        image.setflags(write=False)
        with self._changed:
            self._index += 1
            self._frame = Frame(self._index, time_s, time.monotonic(), image)
            self._changed.notify_all()

    def _run(self) -> None:
        try:
            if self.source.kind == "video":
                self._play_file()
            else:
                self._play_live()
        except _Stop:
            self._set("idle", "no page is asking for frames")
        except PanomapError as exc:
            self._set("failed", str(exc))

    # A file: paced at its rate, paused and sought on request.

    def _play_file(self) -> None:
        while True:
            with self._changed:
                if self._seek_s is not None:
                    self._position_s, self._seek_s = self._seek_s, None
                start_s = self._position_s
            try:
                self._play_file_from(start_s)
                self._set("ended", "the end of the file: seek to play it again")
                while True:
                    self._wait(3600.0)
            except _Seek:
                continue

    def _play_file_from(self, start_s: float) -> None:
        container = open_input(self.source.name) if self._file is None else open_held(self._file)
        try:
            stream = container.streams.video[0]
            stream.thread_type = "AUTO"
            time_base = float(stream.time_base)
            origin = float(stream.start_time * stream.time_base) if stream.start_time is not None else 0.0
            half_frame = 0.5 / (self.source.frame_rate or 25.0)
            if start_s > 0:
                with contextlib.suppress(av.error.FFmpegError):
                    container.seek(int((origin + start_s) / time_base), stream=stream, backward=True)
            self._set("playing", "playing")
            clock: tuple[float, float] | None = None  # (wall s, media s) of the pace's start
            for frame in container.decode(stream):
                if frame.pts is None:
                    continue
                media_s = frame.pts * time_base - origin
                if media_s < start_s - half_frame:
                    continue
                clock = self._pace(clock, media_s)
                self._publish(frame.to_ndarray(format="bgr24"), media_s)
                with self._changed:
                    self._position_s = media_s
        except av.error.FFmpegError as exc:
            raise PanomapError(f"decoding stopped: {reason(exc)}", self.source.name) from None
        finally:
            container.close()

    def _pace(self, clock: tuple[float, float] | None, media_s: float) -> tuple[float, float]:
        """Wait (paused, or until the frame is due) and return the pace's clock for the next frame."""
        with self._changed:
            while self._paused:
                self._check()
                self._changed.wait(0.25)
                clock = None
            self._check()
        now = time.monotonic()
        if clock is None:
            return now, media_s
        due = clock[0] + (media_s - clock[1])
        if due > now:
            self._wait(due - now)
            return clock
        return (now, media_s) if now - due > MAX_LAG_S else clock

    # A live source: frames as they come; reconnected when it drops.

    def _play_live(self) -> None:
        attempt = 0
        while True:
            why, got_frames = self._one_connection()
            if got_frames:
                attempt = 0
            attempt += 1
            if attempt > self.reconnect.attempts:
                self._set(
                    "failed",
                    f"the source dropped ({why}) and did not come back after {self.reconnect.attempts} attempt(s)",
                )
                return
            self._set(
                "reconnecting",
                f"the source dropped ({why}); reconnecting, attempt {attempt} of {self.reconnect.attempts}",
            )
            self._wait(self.reconnect.wait_s(attempt))

    def _one_connection(self) -> tuple[str, bool]:
        """Read one connection to its end: (why it ended, whether it gave any frame)."""
        timeout = self.reconnect.timeout_s
        container, self._connection = self._connection, None
        try:
            if container is None:
                container = open_input(self.source.name, open_timeout=timeout, read_timeout=timeout)
        except PanomapError as exc:
            return exc.detail, False
        got = False
        try:
            stream = container.streams.video[0]
            origin: float | None = None
            self._set("playing", "live")
            for frame in container.decode(stream):
                with self._changed:
                    self._check()
                seconds = float(frame.pts * stream.time_base) if frame.pts is not None else 0.0
                origin = seconds if origin is None else origin
                self._publish(frame.to_ndarray(format="bgr24"), seconds - origin)
                got = True
            ended = "the stream ended" if drops(self.source.name, container) else "the input ended"
            return ended, got
        except av.error.ExitError:
            return f"no data for {timeout:g} s", got
        except av.error.FFmpegError as exc:
            return reason(exc), got
        finally:
            container.close()
