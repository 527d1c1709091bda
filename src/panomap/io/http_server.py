"""An HTTP server for local web tools that a slow or idle client cannot exhaust.

``http.server.ThreadingHTTPServer`` gives every connection a thread for as long as it stays open,
and its socket timeout is per read: a client that sends one byte every few seconds holds its
thread for ever, and 300 idle connections cost 300 threads. Here:

- one watcher thread holds every connection that is not being answered, in a selector, and reads
  what they send without blocking until a request is whole (its head and, by its
  ``Content-Length``, its body); only then does a thread of a pool of ``max_workers`` answer it.
  Idle and slow clients hold no thread, and cannot keep the pool from answering others;
- a request must arrive whole within ``request_deadline_s`` of its first byte (a client sending
  a byte every few seconds is cut off then), and a connection silent for ``idle_timeout_s``
  (between requests, or within one) is closed;
- at most ``max_connections`` connections are open at once; the next is closed on arrival;
- an answer must be taken by the client within ``request_deadline_s`` (a send that waits longer
  ends the connection).

Handlers derive from :class:`WholeRequestHandler` (a ``BaseHTTPRequestHandler`` whose ``rfile``
holds the whole request).
"""

from __future__ import annotations

import io
import re
import selectors
import socket
import sys
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from http.server import BaseHTTPRequestHandler, HTTPServer
from typing import Any

# Seconds a connection may stay silent (before its request, or between requests) before it is closed.
IDLE_TIMEOUT_S = 20.0
# Seconds a whole request may take to arrive, from its first byte (and an answer to be taken).
REQUEST_DEADLINE_S = 10.0
# Threads that answer requests, and connections open at once (those waiting included).
MAX_WORKERS = 8
MAX_CONNECTIONS = 256
# Connections waiting to be accepted (socketserver's default of 5 resets a burst of page requests).
LISTEN_BACKLOG = 128
# A request head longer than this is answered (refused) as it is.
MAX_HEAD_BYTES = 65536
_CONTENT_LENGTH = re.compile(rb"^content-length[ \t]*:[ \t]*(\d+)[ \t]*\r?$", re.IGNORECASE | re.MULTILINE)


@dataclass
class _Connection:
    """A connection between requests: what it has sent of the next one, and since when."""

    sock: socket.socket
    address: Any
    since: float  # when it was parked (monotonic s)
    pending: bytearray = field(default_factory=bytearray)
    first_byte_at: float | None = None  # the request's first byte
    last_byte_at: float | None = None


def whole_request(pending: bytes | bytearray, max_body_bytes: int) -> tuple[int, bool] | None:
    """``(length, complete)`` of the request at the start of ``pending``, or None while more is needed.

    ``complete`` is False where the request is answered without all of it (a head over
    :data:`MAX_HEAD_BYTES`, a body over ``max_body_bytes``: the handler refuses them, and the
    connection closes after).
    """
    head_end = pending.find(b"\r\n\r\n")
    if head_end < 0:
        return (len(pending), False) if len(pending) > MAX_HEAD_BYTES else None
    head = bytes(pending[:head_end])
    match = _CONTENT_LENGTH.search(head)
    body = int(match.group(1)) if match else 0
    if body > max_body_bytes:
        return head_end + 4, False
    need = head_end + 4 + body
    return (need, True) if len(pending) >= need else None


class WholeRequestHandler(BaseHTTPRequestHandler):
    """Answers one request, given whole (``rfile`` is a :class:`io.BytesIO` of it); the server parks the
    connection again unless the handler set ``close_connection``."""

    server: BoundedHTTPServer
    protocol_version = "HTTP/1.1"

    def setup(self) -> None:
        super().setup()
        self.rfile.close()  # (the socket's own reader: every byte of the request is already here)
        self.rfile = io.BytesIO(self.server.request_in_hand())

    def handle(self) -> None:
        self.close_connection = True
        self.handle_one_request()


class BoundedHTTPServer(HTTPServer):
    """An HTTP server with idle connections in a selector, a bounded pool and whole-request deadlines.

    An IPv6 host (one with a ``:``, as ``::1``) gets an IPv6 socket. Stop it with ``shutdown()``
    and ``server_close()`` (which also closes every waiting connection and ends the pool).
    ``max_body_bytes``: the largest request body waited for (a larger one is answered at once,
    which should refuse it, and the connection closed).
    """

    request_queue_size = LISTEN_BACKLOG

    def __init__(
        self,
        address: tuple[str, int],
        handler: type[WholeRequestHandler],
        idle_timeout_s: float = IDLE_TIMEOUT_S,
        request_deadline_s: float = REQUEST_DEADLINE_S,
        max_workers: int = MAX_WORKERS,
        max_connections: int = MAX_CONNECTIONS,
        max_body_bytes: int = 1 << 20,
    ) -> None:
        if ":" in address[0]:
            self.address_family = socket.AF_INET6
        self.idle_timeout_s = idle_timeout_s
        self.request_deadline_s = request_deadline_s
        self.max_connections = max_connections
        self.max_body_bytes = max_body_bytes
        self._handler: type[WholeRequestHandler] = handler
        self._pool = ThreadPoolExecutor(max_workers=max_workers, thread_name_prefix="panomap-http")
        self._in_hand = threading.local()  # the request each pool thread answers
        self._selector = selectors.DefaultSelector()
        self._lock = threading.Lock()
        self._open = 0  # connections accepted and not yet closed
        self._arrivals: list[_Connection] = []  # parked by other threads, for the watcher
        self._wake_read, self._wake_write = socket.socketpair()
        self._wake_read.setblocking(False)
        self._selector.register(self._wake_read, selectors.EVENT_READ, None)
        self._closing = threading.Event()
        self._watcher = threading.Thread(target=self._watch, name="panomap-http-watch", daemon=True)
        self._watcher.start()
        super().__init__(address, handler)  # (a failed bind calls server_close, which ends the above)

    # ------------------------------------------------------------------ connections

    def process_request(self, request: Any, client_address: Any) -> None:
        """A new connection: parked until its request is whole, or closed at once when ``max_connections``
        are open."""
        with self._lock:
            full = self._open >= self.max_connections
            if not full:
                self._open += 1
        if full:
            self.shutdown_request(request)
            return
        self._park(_Connection(request, client_address, time.monotonic()))

    def _park(self, connection: _Connection) -> None:
        connection.sock.setblocking(False)
        with self._lock:
            self._arrivals.append(connection)
        try:
            self._wake_write.send(b"\0")
        except OSError:  # (closing: server_close closes what is left)
            pass

    def _close(self, request: socket.socket) -> None:
        self.shutdown_request(request)
        with self._lock:
            self._open -= 1

    def _answer(self, connection: _Connection, length: int, complete: bool) -> None:
        """Answer the request at the start of ``connection.pending`` (in a pool thread); then park the
        connection with what it sent beyond the request, or close it."""
        request = bytes(connection.pending[:length])
        rest = connection.pending[length:]
        sock = connection.sock
        keep = False
        try:
            sock.setblocking(True)
            sock.settimeout(self.request_deadline_s)  # (for the answer: a client that does not take it)
            self._in_hand.request = request
            handler = self._handler(sock, connection.address, self)
            keep = complete and not handler.close_connection and not self._closing.is_set()
        except Exception:
            self.handle_error(sock, connection.address)
        if not keep:
            self._close(sock)
            return
        parked = _Connection(sock, connection.address, time.monotonic(), bytearray(rest))
        parked.first_byte_at = time.monotonic() if rest else None
        self._park(parked)

    def _read(self, connection: _Connection) -> bool:
        """Take what ``connection`` sent; True when it is to be handed on (a whole request) or closed."""
        try:
            data = connection.sock.recv(65536)
        except BlockingIOError:
            return False
        except OSError:
            data = b""
        if not data:
            self._close(connection.sock)
            return True
        connection.last_byte_at = time.monotonic()
        if connection.first_byte_at is None:
            connection.first_byte_at = connection.last_byte_at
        connection.pending += data
        return self._hand_on(connection)

    def _hand_on(self, connection: _Connection) -> bool:
        """Give a whole request to the pool; True when it went (or the connection closed)."""
        found = whole_request(connection.pending, self.max_body_bytes)
        if found is None:
            return False
        try:
            self._pool.submit(self._answer, connection, *found)
        except RuntimeError:  # (the pool is shut down: closing)
            self._close(connection.sock)
        return True

    def _watch(self) -> None:
        """Park arriving connections, read them, hand whole requests to the pool, close the late and the
        silent."""
        waiting: dict[socket.socket, _Connection] = {}
        while not self._closing.is_set():
            for key, _ in self._selector.select(timeout=0.1):
                if key.fileobj is self._wake_read:
                    try:
                        while self._wake_read.recv(4096):
                            pass
                    except BlockingIOError:
                        pass
                    continue
                connection = waiting[key.fileobj]  # type: ignore[index]
                if self._read(connection):
                    self._selector.unregister(connection.sock)
                    del waiting[connection.sock]
            with self._lock:
                arrivals, self._arrivals = self._arrivals, []
            for connection in arrivals:
                if connection.pending and self._hand_on(connection):  # (a pipelined request, already whole)
                    continue
                waiting[connection.sock] = connection
                self._selector.register(connection.sock, selectors.EVENT_READ, None)
            now = time.monotonic()
            for sock, connection in list(waiting.items()):
                started, last = connection.first_byte_at, connection.last_byte_at or connection.since
                late = started is not None and now - started > self.request_deadline_s
                if late or now - last > self.idle_timeout_s:
                    self._selector.unregister(sock)
                    del waiting[sock]
                    self._close(sock)
        for sock in list(waiting):
            self._close(sock)

    def request_in_hand(self) -> bytes:
        """The whole request the calling pool thread answers (for :class:`WholeRequestHandler`)."""
        return bytes(getattr(self._in_hand, "request", b""))

    # ------------------------------------------------------------------ life

    @property
    def open_connections(self) -> int:
        """Connections accepted and not yet closed (waiting or being answered)."""
        with self._lock:
            return self._open

    def handle_error(self, request: Any, client_address: Any) -> None:
        """A client that went away or fell silent ends its connection quietly; anything else is a bug: shown."""
        if isinstance(sys.exc_info()[1], ConnectionError | TimeoutError):
            return
        super().handle_error(request, client_address)

    def server_close(self) -> None:
        super().server_close()
        self._closing.set()
        try:
            self._wake_write.send(b"\0")
        except OSError:
            pass
        self._watcher.join(timeout=5)
        self._pool.shutdown(wait=False, cancel_futures=True)
        with self._lock:
            arrivals, self._arrivals = self._arrivals, []
        for connection in arrivals:
            self._close(connection.sock)
        self._selector.close()
        self._wake_read.close()
        self._wake_write.close()
