"""What every local web tool of panomap shares (the learning page, the viewer): loopback by default,
``Host`` and ``Origin`` checked, never framed, JSON bodies checked, errors answered as JSON.

A server (:class:`LocalServer`) is a :class:`~panomap.io.http_server.BoundedHTTPServer`: idle and
slow connections hold no thread, a bounded pool answers whole requests, each within a deadline.
A handler (:class:`LocalHandler`) writes its routes in ``_get`` and ``_post``; every request is
first checked:

- on a loopback address the ``Host`` header must name it (against DNS rebinding), 403 otherwise;
- a POST must say ``Content-Type: application/json`` (a cross-site form cannot, so other sites'
  pages cannot drive the server), and its ``Origin``, when sent, must be the page's own (403);
- every answer forbids framing (``X-Frame-Options: DENY``, CSP ``frame-ancestors 'none'``) and
  sniffing, and is not cached;
- errors are ``{"error": "..."}`` with their status, those http.server sends itself (an unknown
  method, a URL or a header too long, a malformed request) too; a bug is answered 500 and shown on
  the terminal.
"""

from __future__ import annotations

import errno
import ipaddress
import json
import math
import threading
from collections.abc import Callable
from http import HTTPStatus
from importlib import resources
from typing import Any, ClassVar, TypeVar

from ..errors import PanomapError
from .http_server import IDLE_TIMEOUT_S, REQUEST_DEADLINE_S, BoundedHTTPServer, WholeRequestHandler

MAX_BODY_BYTES = 1 << 20


class RequestError(PanomapError):
    """A bad request, with the HTTP status to answer it with (400 by default) and more fields for its answer."""

    def __init__(self, message: str, status: int = 400, extra: dict[str, Any] | None = None) -> None:
        super().__init__(message)
        self.status = status
        # More fields of the error's JSON answer, for the page (``{"exists": name}``).
        self.extra = extra or {}


def _refuse_constant(name: str) -> Any:
    raise RequestError(f"the JSON holds {name}; numbers must be finite")


def parse_body(body: bytes) -> dict[str, Any]:
    """A request body as a JSON object (refusing NaN and Infinity, which Python's json accepts)."""
    if len(body) > MAX_BODY_BYTES:
        raise RequestError(f"the request is larger than {MAX_BODY_BYTES} bytes", 413)
    try:
        data = json.loads(body.decode("utf-8"), parse_constant=_refuse_constant)
    except UnicodeDecodeError:
        raise RequestError("the request body is not UTF-8 text") from None
    except json.JSONDecodeError as exc:
        raise RequestError(f"the request body is not valid JSON ({exc})") from None
    except RecursionError:
        raise RequestError("the request body's JSON is nested too deeply") from None
    except ValueError as exc:  # an integer of more digits than Python converts (4300)
        raise RequestError(f"the request body holds a number too long to read ({exc})") from None
    if not isinstance(data, dict):
        raise RequestError("the request body must be a JSON object")
    return data


def only_keys(data: dict[str, Any], allowed: tuple[str, ...], what: str) -> None:
    """Refuse keys the request does not know (a typo would otherwise be ignored)."""
    unknown = sorted(set(data) - set(allowed))
    if unknown:
        raise RequestError(f"{what}: unknown field(s) {', '.join(unknown)}; it takes {', '.join(allowed)}")


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


class LocalServer(BoundedHTTPServer):
    """A :class:`~panomap.io.http_server.BoundedHTTPServer` for a local page: its URL and the ``Host``
    headers it accepts."""

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


ServerT = TypeVar("ServerT", bound=LocalServer)


def bind(factory: Callable[[tuple[str, int]], ServerT], host: str, port: int) -> ServerT:
    """``factory((host, port))``, the host unbracketed; a bind that fails is one clear :class:`PanomapError`.

    ``host`` is a name or an IPv4 or IPv6 address (``::1`` or ``[::1]``); port 0 picks a free one.
    """
    if host.startswith("[") and host.endswith("]"):  # an IPv6 address as written in a URL
        host = host[1:-1]
    try:
        return factory((host, port))
    except OSError as exc:
        shown = f"[{host}]" if ":" in host else host
        # The port is the problem where it is taken or reserved; otherwise the address (no such name, not this
        # machine's).
        remedy = (
            "choose another port (0 picks a free one)"
            if exc.errno in (errno.EADDRINUSE, errno.EACCES)
            else "choose another host (127.0.0.1: this machine alone)"
        )
        raise PanomapError(f"cannot listen on {shown}:{port} ({exc.strerror or exc}); {remedy}") from None


def serve_in_thread(server: LocalServer) -> threading.Thread:
    """Serve in a daemon thread (for tests and scripts); stop with ``server.shutdown()``."""
    name = getattr(server.RequestHandlerClass, "server_version", "panomap-http")
    thread = threading.Thread(target=server.serve_forever, args=(0.05,), name=name, daemon=True)
    thread.start()
    return thread


def page_files(script: str, style: str) -> dict[str, tuple[str, str]]:
    """A page's routes: ``/`` and ``/index.html``, ``/static/<script>`` and ``/static/<style>`` -> (file, type)."""
    html = ("index.html", "text/html; charset=utf-8")
    return {
        "/": html,
        "/index.html": html,
        f"/static/{script}": (script, "text/javascript; charset=utf-8"),
        f"/static/{style}": (style, "text/css; charset=utf-8"),
    }


class LocalHandler(WholeRequestHandler):
    """Checks every request (see the module docstring) and routes it to ``_get`` or ``_post``.

    A handler's page is ``static_files`` (URL path -> (file, content type), :func:`page_files`), shipped
    in the package ``static_package``'s ``static`` folder; :meth:`_page` answers them.
    """

    server: LocalServer
    content_security_policy = "default-src 'self'; img-src 'self' blob: data:; frame-ancestors 'none'"
    max_body_bytes = MAX_BODY_BYTES
    static_package: ClassVar[str] = ""
    static_files: ClassVar[dict[str, tuple[str, str]]] = {}

    def _page(self, path: str) -> bool:
        """Answer ``path`` with the page's file where it is one of ``static_files``; False otherwise."""
        if path not in self.static_files:
            return False
        name, content_type = self.static_files[path]
        self._send(200, resources.files(self.static_package).joinpath("static", name).read_bytes(), content_type)
        return True

    def log_message(self, format: str, *args: Any) -> None:
        """Quiet: the terminal shows the address and errors, not every request."""

    # ------------------------------------------------------------------ answers

    def send_common_headers(self, content_type: str) -> None:
        """The headers of every answer: type, no caching, no sniffing, no framing."""
        self.send_header("Content-Type", content_type)
        self.send_header("Cache-Control", "no-store")
        self.send_header("X-Content-Type-Options", "nosniff")
        self.send_header("Content-Security-Policy", self.content_security_policy)
        self.send_header("X-Frame-Options", "DENY")
        if self.close_connection:
            self.send_header("Connection", "close")

    def _send(self, status: int, body: bytes, content_type: str, headers: dict[str, str] | None = None) -> None:
        self.send_response(status)
        self.send_header("Content-Length", str(len(body)))
        for name, value in (headers or {}).items():
            self.send_header(name, value)
        self.send_common_headers(content_type)
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

    def send_error(self, code: int, message: str | None = None, explain: str | None = None) -> None:
        """http.server's own refusals (an unknown method, a request line or a header too long, too many
        headers, a malformed request) answered as every error is: JSON, with the security headers of every
        answer, the connection closed."""
        if getattr(self, "request_version", "") == "HTTP/0.9":  # (a request line that did not parse)
            self.request_version = "HTTP/1.0"  # (an HTTP/0.9 answer has no status line and no headers)
        try:
            phrase = HTTPStatus(code).phrase
        except ValueError:
            phrase = "refused"
        self._error(code, (message or phrase)[:200])

    def parse_request(self) -> bool:
        """http.server's reading of the request, refusing HTTP/0.9 (whose answers carry no headers)."""
        if not super().parse_request():
            return False
        if self.request_version == "HTTP/0.9":
            self.send_error(HTTPStatus.HTTP_VERSION_NOT_SUPPORTED, "HTTP/0.9 requests are not answered")
            return False
        return True

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

    def _body(self) -> dict[str, Any]:
        """The request's JSON object (it must say ``Content-Type: application/json``)."""
        content_type = self.headers.get("Content-Type", "").split(";")[0].strip().lower()
        if content_type != "application/json":
            raise RequestError("send the request as JSON (Content-Type: application/json)", 415)
        try:
            length = int(self.headers.get("Content-Length", ""))
        except ValueError:
            raise RequestError("the request has no Content-Length") from None
        if length < 0 or length > self.max_body_bytes:
            self.close_connection = True
            raise RequestError(f"the request is larger than {self.max_body_bytes} bytes", 413)
        return parse_body(self.rfile.read(length))

    # ------------------------------------------------------------------ methods

    def do_GET(self) -> None:
        self._guarded(self._get)

    def do_HEAD(self) -> None:
        self._guarded(self._get)

    def do_POST(self) -> None:
        self._guarded(self._checked_post)

    def do_PUT(self) -> None:
        self._guarded(self._not_allowed)

    do_DELETE = do_PATCH = do_PUT

    def _checked_post(self) -> None:
        self._check_origin()
        self._post()

    def _not_allowed(self) -> None:
        self._check_origin()
        raise RequestError(f"{self.command} is not supported here", HTTPStatus.METHOD_NOT_ALLOWED)

    def _get(self) -> None:
        raise RequestError(f"no such page: {self.path[:200]}", 404)

    def _post(self) -> None:
        raise RequestError(f"no such API: POST {self.path[:200]}", 404)


__all__ = [
    "IDLE_TIMEOUT_S",
    "MAX_BODY_BYTES",
    "REQUEST_DEADLINE_S",
    "LocalHandler",
    "LocalServer",
    "RequestError",
    "bind",
    "is_loopback",
    "json_safe",
    "only_keys",
    "page_files",
    "parse_body",
    "serve_in_thread",
]
