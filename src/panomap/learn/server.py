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

from typing import ClassVar
from urllib.parse import urlsplit

from ..io.local_web import (
    IDLE_TIMEOUT_S,
    REQUEST_DEADLINE_S,
    LocalHandler,
    LocalServer,
    RequestError,
    bind,
    is_loopback,
    json_safe,
    only_keys,
    page_files,
    serve_in_thread,
)
from .session import Session
from .validate import MAX_BODY_BYTES


class LearnServer(LocalServer):
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


class LearnHandler(LocalHandler):
    """Routes the page's requests to the session."""

    server: LearnServer
    server_version = "panomap-learn"
    static_package: ClassVar[str] = "panomap.learn"
    static_files: ClassVar[dict[str, tuple[str, str]]] = page_files("app.js", "app.css")

    def _get(self) -> None:
        path = urlsplit(self.path).path
        if self._page(path):
            return
        session = self.server.session
        if path == "/api/state":
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

    def _post(self) -> None:
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
    return bind(lambda address: LearnServer(address, session, idle_timeout_s, request_deadline_s), host, port)


__all__ = ["LearnServer", "is_loopback", "json_safe", "make_server", "serve_in_thread"]
