"""The viewer's web server: the page, the table's texture, and the source (an image, a video file with
range requests, or decoded frames).

API (GET unless said; errors are ``{"error": "..."}`` with their status):

- ``/api/info``: JSON ``{"table": {...}, "source": {...}}`` (:func:`~panomap.viewer.table_texture.table_description`;
  the source's kind ``image``, ``video`` or ``live``, size, and for a video its MIME type where a browser
  plays it itself, its length and frame rate).
- ``/api/table.bin``: the table's entries as float32 texture data; ``/api/lookup.bin``: its direction
  lookup (what the CLI's perspective and floor views read), where it has one.
- ``/api/image``: a still image (PNG).
- ``/api/video``: a video file, as it is, with HTTP range requests (at most :data:`MAX_RANGE_BYTES`
  an answer: a browser asks for the rest). The file is opened once, when the server starts
  (:class:`~panomap.viewer.source.HeldFile`): a link swapped or a file replaced later changes nothing
  that is sent or decoded.
- ``/api/frame?after=K[&window=X0,Y0,W,H]``: the newest decoded frame (JPEG; only the window's pixels
  where one is given) when its index is above K, waiting up to a second for one; 204 when none came.
  Headers ``X-Frame-Index``, ``X-Frame-Time`` (s), ``X-Frame-Age`` (s since it was decoded) and
  ``X-Frame-Window`` (the window sent, clipped to the frame).
- A rig (:mod:`panomap.viewer.rig_view`; ``info`` then has ``rig``, its cameras, and ``table`` is camera 0's):
  ``/api/rig/lookup.bin?camera=K``, camera K's lookup with its edge (:func:`~.rig_view.rig_lookup`);
  ``/api/gains?view=SPEC``, JSON ``{"gains": [[...], ...]}``, each camera's gains (BGR) in the view SPEC
  (``panomap.views.spec``) as the view commands find them.
- ``/api/status``: the decoded frames' state (playing, paused, ended, reconnecting, failed) in words.
- POST ``/api/playback`` ``{"paused": bool, "seek_s": s}`` (either): pause, play or seek a decoded file.

Security as the learning page's (:mod:`panomap.io.local_web`): loopback by default, ``Host`` and
``Origin`` checked, never framed, bounded connections and a deadline per request. Nothing is served
but the page, the table and the one source given.
"""

from __future__ import annotations

import dataclasses
import re
import time
from pathlib import Path
from typing import Any, ClassVar
from urllib.parse import parse_qs, urlsplit

from ..errors import PanomapError
from ..io.local_web import (
    IDLE_TIMEOUT_S,
    REQUEST_DEADLINE_S,
    LocalHandler,
    LocalServer,
    RequestError,
    bind,
    only_keys,
    page_files,
    serve_in_thread,
)
from ..table.table import PanoMappingTable
from ..values import MAX_ABS, NotFinite, finite_number
from .feed import FrameFeed, window_of
from .rig_view import RigView
from .source import HeldFile, Source
from .table_texture import lookup_texture, table_description, texture_bytes

# The most bytes of a video one answer carries (a browser asks for the rest as it plays).
MAX_RANGE_BYTES = 8 << 20
# The longest wait (s) for a new frame within one request.
MAX_FRAME_WAIT_S = 1.0
CHUNK_BYTES = 1 << 20
# The longest view spec a page asks a rig's gains for.
MAX_SPEC_CHARS = 400
_RANGE = re.compile(r"^bytes=([0-9]*)-([0-9]*)$")
# Digits read of a number in a request: more is beyond any file, frame or index (and Python refuses to convert
# an integer of over 4300 digits).
MAX_DIGITS = 18
BEYOND = 10**MAX_DIGITS  # what a number of more digits reads as


def bounded_int(text: str) -> int:
    """The whole number ``text`` (ASCII digits, an optional ``-``), or :data:`BEYOND` (``-BEYOND``) where it has
    more than :data:`MAX_DIGITS` digits: larger than anything it can count.

    Raises
    ------
    ValueError
        When ``text`` is not a whole number.
    """
    digits = text[1:] if text.startswith("-") else text
    if not digits or not digits.isascii() or not digits.isdigit():
        raise ValueError(f"not a whole number: {text[:40]!r}")
    digits = digits.lstrip("0") or "0"
    value = int(digits) if len(digits) <= MAX_DIGITS else BEYOND
    return -value if text.startswith("-") else value


def byte_range(header: str | None, size: int) -> tuple[int, int] | None:
    """The (first, last) bytes, inclusive, that a ``Range`` header asks of a file of ``size`` bytes, at most
    :data:`MAX_RANGE_BYTES` of them; None without a header. Numbers of any length are read (one beyond
    :data:`MAX_DIGITS` digits as beyond the file).

    Raises
    ------
    RequestError
        416 for a range that is malformed, of several parts, or outside the file.
    """
    if header is None:
        return None
    match = _RANGE.match(header.strip())
    if match is None or match.group(1) == match.group(2) == "":
        raise RequestError(f"unsupported range {header[:60]!r} (one bytes=FIRST-LAST range)", 416)
    first_text, last_text = match.groups()
    if first_text == "":  # the last N bytes
        first, last = max(0, size - bounded_int(last_text)), size - 1
    else:
        first = bounded_int(first_text)
        last = size - 1 if last_text == "" else min(bounded_int(last_text), size - 1)
    if first >= size or last < first:
        raise RequestError(f"the range {header[:60]!r} lies outside the file ({size} bytes)", 416, {"size": size})
    return first, min(last, first + MAX_RANGE_BYTES - 1)


class ViewerServer(LocalServer):
    """An HTTP server for one table and one source (see the module docstring)."""

    def __init__(
        self,
        address: tuple[str, int],
        table: PanoMappingTable,
        table_name: str,
        source: Source,
        feed: FrameFeed | None = None,
        idle_timeout_s: float = IDLE_TIMEOUT_S,
        request_deadline_s: float = REQUEST_DEADLINE_S,
        rig: RigView | None = None,
    ) -> None:
        self.table = table
        self.source = source
        self.rig = rig
        self.info: dict[str, Any] = {
            "table": table_description(table) | {"name": table_name},
            "source": {
                "name": Path(source.name).name if source.kind != "live" else source.name,
                "kind": source.kind,
                "size": list(source.size),
                "mime": source.mime,
                "duration_s": source.duration_s,
                "frame_rate": source.frame_rate,
            },
        }
        if rig is None:
            self.table_bytes = texture_bytes(table)
            lookup = lookup_texture(table)
            self.lookup_bytes = None if lookup is None else lookup[0].astype("<f4", copy=False).tobytes()
            self.info["table"]["lookup"] = None if lookup is None else lookup[1]
        else:  # (the page reads each camera's lookup; the table is camera 0's, for the views' defaults)
            self.table_bytes, self.lookup_bytes = b"", None
            self.info["table"]["lookup"] = None
            self.info["rig"] = rig.textures.description | {"pictures": list(rig.pictures)}
        # A video file is opened once, here: what is sent and decoded, whatever its name points to later.
        self.file = HeldFile(source.name) if source.kind == "video" and source.path is not None else None
        self.feed = feed
        if feed is None and source.kind != "image":
            self.feed = FrameFeed(source, file=self.file)
        super().__init__(address, ViewerHandler, idle_timeout_s, request_deadline_s)  # (a failed bind closes)

    def server_close(self) -> None:
        super().server_close()
        if self.feed is not None:
            self.feed.close()
        if self.file is not None:
            self.file.close()


class ViewerHandler(LocalHandler):
    """Routes the page's requests (see the module docstring)."""

    server: ViewerServer
    server_version = "panomap-view"
    static_package: ClassVar[str] = "panomap.viewer"
    static_files: ClassVar[dict[str, tuple[str, str]]] = page_files("viewer.js", "viewer.css") | {
        "/static/viewer_rig.js": ("viewer_rig.js", "text/javascript; charset=utf-8")
    }
    content_security_policy = (
        "default-src 'self'; img-src 'self' blob: data:; media-src 'self' blob:; frame-ancestors 'none'"
    )

    def _get(self) -> None:
        parts = urlsplit(self.path)
        path = parts.path
        if self._page(path):
            return
        server = self.server
        if path == "/api/info":
            self._json(server.info)
        elif path == "/api/table.bin":
            self._send(200, server.table_bytes, "application/octet-stream")
        elif path == "/api/lookup.bin" and server.lookup_bytes is not None:
            self._send(200, server.lookup_bytes, "application/octet-stream")
        elif path.startswith("/api/rig/") or path == "/api/gains":
            self._rig(path, parse_qs(parts.query))
        elif path == "/favicon.ico":
            self._send(204, b"", "image/x-icon")
        elif path == "/api/image" and server.source.image_png is not None:
            self._send(200, server.source.image_png, "image/png")
        elif path == "/api/video" and server.source.mime is not None and server.file is not None:
            self._video(server.file, server.source.mime)
        elif path == "/api/frame" and server.feed is not None:
            self._frame(server.feed, parse_qs(parts.query))
        elif path == "/api/status" and server.feed is not None:
            self._json(dataclasses.asdict(server.feed.status()))
        elif path.startswith("/api/"):
            raise RequestError(f"no such API for this source: GET {path[:200]}", 404)
        else:
            raise RequestError(f"no such page: {path[:200]}", 404)

    def _rig(self, path: str, query: dict[str, list[str]]) -> None:
        """A rig's lookups, edges and gains (see the module docstring)."""
        rig = self.server.rig
        if rig is None:
            raise RequestError(f"no such API for a table: GET {path[:200]}", 404)
        if path == "/api/rig/lookup.bin":
            text = query.get("camera", [""])[0]
            count = len(rig.textures.lookups)
            if not (0 < len(text) <= 3 and text.isascii() and text.isdigit() and int(text) < count):
                raise RequestError(f"camera must be a camera's index, 0 to {count - 1}")
            self._send(200, rig.textures.lookups[int(text)], "application/octet-stream")
        elif path == "/api/gains":
            spec = query.get("view", [""])[0]
            if not spec or len(spec) > MAX_SPEC_CHARS:
                raise RequestError(f"view must be a view spec of at most {MAX_SPEC_CHARS} characters")
            try:
                gains = rig.gains(spec)
            except PanomapError as exc:
                raise RequestError(f"view: {exc}") from None
            self._json({"gains": gains})
        else:
            raise RequestError(f"no such API: GET {path[:200]}", 404)

    def _post(self) -> None:
        path = urlsplit(self.path).path
        if path != "/api/playback":
            raise RequestError(f"no such API: POST {path[:200]}", 404)
        data = self._body()
        only_keys(data, ("paused", "seek_s"), path)
        feed = self.server.feed
        if feed is None or self.server.source.kind != "video":
            raise RequestError("only a video file's decoded frames can be paused or sought", 409)
        paused = data.get("paused")
        if paused is not None and not isinstance(paused, bool):
            raise RequestError(f"{path}: paused must be true or false")
        feed.control(paused, _seek_time(data.get("seek_s"), path))
        self._json({"ok": True})

    def _frame(self, feed: FrameFeed, query: dict[str, list[str]]) -> None:
        after, window = _frame_query(query)
        frame = feed.frame_after(after, MAX_FRAME_WAIT_S)
        if frame is None:
            self.send_response(204)
            self.send_header("X-Feed-State", feed.status().state)
            self.send_common_headers("text/plain")
            self.end_headers()
            return
        box = window_of(self.server.source.size, window)
        body = feed.jpeg(frame, box)
        headers = {
            "X-Frame-Index": str(frame.index),
            "X-Frame-Time": f"{frame.time_s:.6f}",
            "X-Frame-Age": f"{time.monotonic() - frame.decoded_at:.6f}",
            "X-Frame-Window": ",".join(str(v) for v in box),
        }
        self._send(200, body, "image/jpeg", headers)

    def _video(self, file: HeldFile, mime: str) -> None:
        """The video file held since the server started, whole or the range asked for."""
        size = file.size
        wanted = byte_range(self.headers.get("Range"), size)
        first, last = wanted if wanted is not None else (0, size - 1)
        self.send_response(206 if wanted is not None else 200)
        self.send_header("Content-Length", str(last - first + 1))
        self.send_header("Accept-Ranges", "bytes")
        if wanted is not None:
            self.send_header("Content-Range", f"bytes {first}-{last}/{size}")
        self.send_common_headers(mime)
        self.end_headers()
        if self.command == "HEAD":
            return
        at, end = first, last + 1
        while at < end:
            try:
                chunk = file.read_at(at, min(CHUNK_BYTES, end - at))
            except (OSError, ValueError):  # (the server closes meanwhile)
                chunk = b""
            if not chunk:
                self.close_connection = True  # (the file shrank: the client sees a short answer)
                return
            self.wfile.write(chunk)
            at += len(chunk)


def _seek_time(value: object, path: str) -> float | None:
    """A request's ``seek_s``: None, or a time of at least 0 s and at most :data:`~panomap.values.MAX_ABS`."""
    if value is None:
        return None
    problem = f"{path}: seek_s must be a time of at least 0 s and at most {MAX_ABS:g} s"
    if not isinstance(value, int | float):
        raise RequestError(problem)
    try:
        seconds = finite_number(value, bools=False)
    except NotFinite:
        raise RequestError(problem) from None
    if seconds < 0:
        raise RequestError(problem)
    return seconds


def _frame_query(query: dict[str, list[str]]) -> tuple[int, tuple[int, int, int, int] | None]:
    """``/api/frame``'s ``after`` (the index of the frame the page has) and ``window`` (x0, y0, width, height)."""
    try:
        after = bounded_int(query.get("after", ["0"])[0])
    except ValueError:
        raise RequestError("after must be a whole number (the index of the frame the page has)") from None
    if abs(after) >= BEYOND:
        raise RequestError(f"after must be a whole number of at most {MAX_DIGITS} digits")
    if "window" not in query:
        return after, None
    try:
        x0, y0, w, h = (bounded_int(v) for v in query["window"][0].split(","))
    except ValueError:
        raise RequestError("window must be X0,Y0,WIDTH,HEIGHT in whole pixels") from None
    if max(abs(x0), abs(y0), abs(w), abs(h)) >= BEYOND:
        raise RequestError(f"window must be X0,Y0,WIDTH,HEIGHT in whole pixels of at most {MAX_DIGITS} digits")
    return after, (x0, y0, w, h)


def make_server(
    table: PanoMappingTable,
    table_name: str,
    source: Source,
    host: str = "127.0.0.1",
    port: int = 0,
    feed: FrameFeed | None = None,
    rig: RigView | None = None,
) -> ViewerServer:
    """A viewer server bound to ``host:port`` (0: a free port), not yet serving (:func:`~panomap.io.local_web.bind`);
    with ``rig``, of that rig (``table`` its camera 0's, ``source`` its pictures:
    :func:`~.rig_view.open_rig_source`)."""
    return bind(lambda address: ViewerServer(address, table, table_name, source, feed, rig=rig), host, port)


__all__ = ["ViewerHandler", "ViewerServer", "byte_range", "make_server", "serve_in_thread"]
