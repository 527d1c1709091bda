"""The learning page's web server: static files and a small JSON API over a :class:`Session`.

Standard library only (:mod:`panomap.io.http_server`: idle connections hold no thread, a bounded
pool serves requests, a whole request must arrive within a deadline), bound to the loopback
address by default. The handler parses requests and calls the
session; it holds no geometry.

API (bodies and answers are JSON unless said otherwise; errors are
``{"error": "..."}`` with status 400, 404, 405, 409, 413 or 415):

- ``GET /api/state``: image, circles, camera, landmarks, model, fit.
- ``POST /api/state`` ``{"camera": [X0, Y0, Z0] | null, "circles": {"centre": [u0, v0],
  "cutoff_radius": r, "outer_radius": R}, "landmarks": [{"name", "u", "v", "X", "Y", "Z"}],
  "model": "auto"}`` (any subset): replace, refit, answer the state.
- ``GET /api/image``: the omni-image (PNG). ``GET /api/panorama.png``: the generic
  panorama of the current fit (720 x 180 PNG; 409 without a fit).
- ``GET /api/files``: landmark and table files in the folder.
- ``POST /api/landmarks/save`` ``{"name": "landmarks.csv"}`` (or ``.json``),
  ``POST /api/landmarks/load`` ``{"name": ...}``, ``POST /api/table/save``
  ``{"name": "cam.npz"}``: bare names in the server's folder only.
- ``POST /api/lines`` ``{}``: learn the camera from the image's straight lines (no landmark needed),
  answer the state (its ``"lines"``: the report's sentences and figures, every line used and every
  arc set aside with its points, the centre, the tilt, the azimuth origin, the horizon).
- ``POST /api/lines/azimuth`` ``{"u": u, "v": v}``: the pixel that sees world azimuth 0 on the
  camera learned from lines (``--azimuth-zero U V``; 409 before learning), answer the state.
- ``POST /api/lines/save`` ``{"name": "lines.npz"}``: the table learned from lines, as the saves above.

POSTs must say ``Content-Type: application/json`` (a cross-site form cannot, so
other sites' pages cannot drive the server), a POST's ``Origin``, when sent, must
be the page's own (403 otherwise), and on a loopback address the ``Host`` header
must name it (against DNS rebinding). Every answer forbids framing
(``X-Frame-Options: DENY``, CSP ``frame-ancestors 'none'``). The saves refuse
to replace an existing file (409, with ``"exists": name``) unless the body says
``"overwrite": true``.

Connections idle for ``IDLE_TIMEOUT_S`` (a half-open one, a client that stops
sending) are closed, and so is one whose request has not arrived whole within
``REQUEST_DEADLINE_S`` of its first byte (a client sending a byte every few seconds).
"""

from __future__ import annotations

import ipaddress
import json
import math
import threading
from http import HTTPStatus
from importlib import resources
from typing import Any
from urllib.parse import urlsplit

from ..errors import PanomapError
from ..io.http_server import IDLE_TIMEOUT_S, REQUEST_DEADLINE_S, BoundedHTTPServer, WholeRequestHandler
from .session import Session
from .validate import MAX_BODY_BYTES, RequestError, only_keys, parse_body

CONTENT_SECURITY_POLICY = "default-src 'self'; img-src 'self' blob: data:; frame-ancestors 'none'"

STATIC_FILES = {
    "/": ("index.html", "text/html; charset=utf-8"),
    "/index.html": ("index.html", "text/html; charset=utf-8"),
    "/static/app.js": ("app.js", "text/javascript; charset=utf-8"),
    "/static/app.css": ("app.css", "text/css; charset=utf-8"),
}


def static_file(name: str) -> bytes:
    """A front-end file shipped in ``panomap/learn/static``."""
    return resources.files("panomap.learn").joinpath("static", name).read_bytes()


def json_safe(data: Any) -> Any:
    """``data`` with every non-finite float replaced by None (JSON has no NaN)."""
    if isinstance(data, float):
        return data if math.isfinite(data) else None
    if isinstance(data, dict):
        return {k: json_safe(v) for k, v in data.items()}
    if isinstance(data, list | tuple):
        return [json_safe(v) for v in data]
    return data


def is_loopback(host: str) -> bool:
    """True for ``localhost`` and loopback addresses (127.0.0.0/8, ::1)."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def _host_text(host: str | bytes | bytearray) -> str:
    return host if isinstance(host, str) else bytes(host).decode("ascii")


class LearnServer(BoundedHTTPServer):
    """An HTTP server holding the session it serves (:class:`~panomap.io.http_server.BoundedHTTPServer`:
    idle and slow connections hold no thread, a bounded pool answers whole requests, a request must
    arrive whole within ``request_deadline_s`` and a silent connection closes after ``idle_timeout_s``)."""

    def __init__(
        self,
        address: tuple[str, int],
        session: Session,
        idle_timeout_s: float = IDLE_TIMEOUT_S,
        request_deadline_s: float = REQUEST_DEADLINE_S,
    ) -> None:
        self.session = session
        super().__init__(address, LearnHandler, idle_timeout_s, request_deadline_s, max_body_bytes=MAX_BODY_BYTES)

    @property
    def url(self) -> str:
        host, port = _host_text(self.server_address[0]), self.server_address[1]
        shown = f"[{host}]" if ":" in host else host
        return f"http://{shown}:{port}/"

    def allowed_hosts(self) -> set[str] | None:
        """Host headers accepted on a loopback server; None (any) when bound elsewhere."""
        host, port = _host_text(self.server_address[0]), self.server_address[1]
        if not is_loopback(host):
            return None
        names = {host, "localhost", "127.0.0.1", "[::1]", f"[{host}]"}
        return {f"{name}:{port}" for name in names}


class LearnHandler(WholeRequestHandler):
    """Routes the page's requests to the session."""

    server: LearnServer
    server_version = "panomap-learn"

    def log_message(self, format: str, *args: Any) -> None:
        """Quiet: the terminal shows the address and errors, not every request."""

    # ------------------------------------------------------------------ answers

    def _send(self, status: int, body: bytes, content_type: str) -> None:
        self.send_response(status)
        self.send_header("Content-Type", content_type)
        self.send_header("Content-Length", str(len(body)))
        self.send_header("Cache-Control", "no-store")
        self.send_header("X-Content-Type-Options", "nosniff")
        self.send_header("Content-Security-Policy", CONTENT_SECURITY_POLICY)
        self.send_header("X-Frame-Options", "DENY")
        if self.close_connection:
            self.send_header("Connection", "close")
        self.end_headers()
        if self.command != "HEAD":
            self.wfile.write(body)

    def _json(self, data: Any, status: int = 200) -> None:
        try:
            text = json.dumps(data, allow_nan=False)
        except ValueError:  # a NaN or infinity somewhere in a report: JSON has none, send null
            text = json.dumps(json_safe(data), allow_nan=False)
        self._send(status, text.encode("utf-8"), "application/json")

    def _error(self, status: int, message: str, extra: dict[str, Any] | None = None) -> None:
        # The request's body may be unread: end the connection rather than parse it as the next request.
        self.close_connection = True
        self._json({"error": message} | (extra or {}), status)

    def _guarded(self, action: Any) -> None:
        try:
            if not self._host_ok():
                raise RequestError("this server answers only requests addressed to it by its loopback name", 403)
            action()
        except RequestError as exc:
            self._error(exc.status, exc.detail, exc.extra)
        except PanomapError as exc:
            self._error(400, str(exc))
        except Exception as exc:  # a bug: say so on the page and keep serving
            self._error(500, f"internal error ({exc.__class__.__name__}: {exc})")
            raise

    def _host_ok(self) -> bool:
        allowed = self.server.allowed_hosts()
        return allowed is None or self.headers.get("Host", "") in allowed

    def _check_origin(self) -> None:
        """Refuse a state-changing request sent by another site's page (a browser says whose in ``Origin``).

        Scripts (curl, urllib) send no ``Origin``: they are let through, as the
        ``Host`` and ``Content-Type`` checks already bind them to this server.
        """
        origin = self.headers.get("Origin")
        if origin is not None and origin != f"http://{self.headers.get('Host', '')}":
            raise RequestError(f"refused a request sent from another site's page (Origin {origin[:80]})", 403)

    # ------------------------------------------------------------------ methods

    def do_GET(self) -> None:
        self._guarded(self._get)

    def do_HEAD(self) -> None:
        self._guarded(self._get)

    def do_POST(self) -> None:
        self._guarded(self._post)

    def do_PUT(self) -> None:
        self._guarded(self._not_allowed)

    do_DELETE = do_PATCH = do_PUT

    def _not_allowed(self) -> None:
        self._check_origin()
        raise RequestError(f"{self.command} is not supported here", HTTPStatus.METHOD_NOT_ALLOWED)

    def _get(self) -> None:
        path = urlsplit(self.path).path
        session = self.server.session
        if path in STATIC_FILES:
            name, content_type = STATIC_FILES[path]
            self._send(200, static_file(name), content_type)
        elif path == "/api/state":
            self._json(session.state())
        elif path == "/api/image":
            self._send(200, session.image_png, "image/png")
        elif path == "/api/panorama.png":
            self._send(200, session.panorama_png(), "image/png")
        elif path == "/api/files":
            self._json(session.files())
        elif path.startswith("/api/"):
            raise RequestError(f"no such API: GET {path}", 404)
        else:
            raise RequestError(f"no such page: {path}", 404)

    def _body(self) -> dict[str, Any]:
        content_type = self.headers.get("Content-Type", "").split(";")[0].strip().lower()
        if content_type != "application/json":
            raise RequestError("send the request as JSON (Content-Type: application/json)", 415)
        try:
            length = int(self.headers.get("Content-Length", ""))
        except ValueError:
            raise RequestError("the request has no Content-Length") from None
        if length < 0 or length > MAX_BODY_BYTES:
            self.close_connection = True
            raise RequestError(f"the request is larger than {MAX_BODY_BYTES} bytes", 413)
        return parse_body(self.rfile.read(length))

    def _post(self) -> None:
        self._check_origin()
        path = urlsplit(self.path).path
        session = self.server.session
        routes = {
            "/api/state",
            "/api/landmarks/save",
            "/api/landmarks/load",
            "/api/table/save",
            "/api/lines",
            "/api/lines/azimuth",
            "/api/lines/save",
        }
        if path not in routes:
            raise RequestError(f"no such API: POST {path}", 404)
        data = self._body()
        if path == "/api/state":
            self._json(session.update(data))
        elif path == "/api/lines":
            self._json(session.learn_lines(data))
        elif path == "/api/lines/azimuth":
            self._json(session.line_azimuth(data))
        elif path == "/api/landmarks/load":
            only_keys(data, ("name",), path)
            self._json(session.load_landmarks(data.get("name")))
        else:
            only_keys(data, ("name", "overwrite"), path)
            overwrite = data.get("overwrite", False)
            if not isinstance(overwrite, bool):
                raise RequestError(f"{path}: overwrite must be true or false")
            saves = {"/api/landmarks/save": session.save_landmarks, "/api/lines/save": session.save_line_table}
            save = saves.get(path, session.save_table)
            self._json({"wrote": save(data.get("name"), overwrite=overwrite)})


def make_server(
    session: Session,
    host: str = "127.0.0.1",
    port: int = 0,
    idle_timeout_s: float = IDLE_TIMEOUT_S,
    request_deadline_s: float = REQUEST_DEADLINE_S,
) -> LearnServer:
    """A server for ``session`` bound to ``host:port`` (port 0: a free one), not yet serving.

    ``host`` is a name or an IPv4 or IPv6 address (``::1``); connections silent for
    ``idle_timeout_s`` seconds are closed, and so are those whose request has not arrived whole
    ``request_deadline_s`` seconds after its first byte.

    Raises
    ------
    PanomapError
        When the address cannot be bound (the port is in use, the host is not this machine's).
    """
    if host.startswith("[") and host.endswith("]"):  # an IPv6 address as written in a URL
        host = host[1:-1]
    try:
        return LearnServer((host, port), session, idle_timeout_s, request_deadline_s)
    except OSError as exc:
        shown = f"[{host}]" if ":" in host else host
        raise PanomapError(
            f"cannot listen on {shown}:{port} ({exc.strerror or exc}); choose another --port (0 picks a free one)"
        ) from None


def serve_in_thread(server: LearnServer) -> threading.Thread:
    """Serve in a daemon thread (for tests and scripts); stop with ``server.shutdown()``."""
    thread = threading.Thread(target=server.serve_forever, args=(0.05,), name="panomap-learn", daemon=True)
    thread.start()
    return thread
