"""The page's web server: Starlette with one WebSocket, served by uvicorn in a background
thread on 127.0.0.1 only (``pip install 'tlac[human]'``).

Safe by default:

* bound to the loopback address; no option binds another;
* a random token (:func:`new_token`) is required on every request and on the WebSocket
  handshake (``?token=``): without it, HTTP 403 and a refused handshake, before any route;
* the ``Host`` header of every request and handshake must be ``127.0.0.1:PORT`` or
  ``localhost:PORT`` (a DNS-rebinding page names its own host), and a handshake's ``Origin``,
  when the browser sends one, the page's own (``http://`` and that host: a cross-site page
  cannot open the socket); refused like a wrong token, before any route;
* every message from the page is parsed strictly (:func:`parse_message`): JSON objects of a
  known type with exactly its fields, action ids among the buttons, at most
  :data:`MAX_MESSAGE` bytes; anything else is refused, counted and logged (the first few in
  full, then one line per thousand), never raised into the run;
* at most :data:`RATE` messages a second per page (a burst of :data:`BURST`); the rest of a
  flood is dropped as it arrives, so it neither grows memory nor reaches the run.
"""

from __future__ import annotations

import asyncio
import collections
import contextlib
import hmac
import json
import logging
import secrets
import threading
import time
from collections import Counter
from importlib import resources
from typing import Any
from urllib.parse import parse_qs

from tlac.errors import ConfigError, require_extra

require_extra("human", "tlac teach (a person as a teacher)", "starlette", "uvicorn")

from starlette.applications import Starlette  # noqa: E402
from starlette.responses import HTMLResponse, PlainTextResponse, Response  # noqa: E402
from starlette.routing import Route, WebSocketRoute  # noqa: E402
from starlette.websockets import WebSocket, WebSocketDisconnect  # noqa: E402

from tlac.human.desk import Desk  # noqa: E402

LOG = logging.getLogger("tlac.human")
HOST = "127.0.0.1"
MAX_MESSAGE = 1024
"""Bytes a message from the page may have (an answer is about 40)."""
RATE = 30.0
"""Messages a second a page may send, on average (a person presses far fewer keys)."""
BURST = 60
"""Messages a page may send at once before the rate applies."""
OUTBOX = 256
"""Messages waiting to go to one page (:class:`Outbox`); the oldest progress reports give
way first."""
LOGGED_IN_FULL = 10
"""Refusals logged one by one; after them, one line per thousand."""
REQUEST_REASONS = (
    "http token",
    "http Host",
    "websocket token",
    "websocket Host",
    "websocket Origin",
)
"""Why an HTTP request or WebSocket handshake is refused (:func:`check_request`)."""
MESSAGE_REASONS = (
    "not text",
    "too long",
    "not JSON",
    "not an object",
    "unknown type",
    "fields",
    "bad value",
    "flood",
    "not pending",
)
"""Why a message from the page is refused (:func:`parse_message`, the rate limit, an answer
to a question that is not waiting): :attr:`Refusals.counts`' keys are these and
:data:`REQUEST_REASONS`, the details go to the log only."""

MESSAGE_FIELDS = {
    "answer": {"type", "id", "action"},
    "takeover": {"type", "on"},
    "here": {"type"},
}


def new_token() -> str:
    """A random token for the page's URL (128 bits)."""
    return secrets.token_urlsafe(16)


def page_html() -> str:
    """The page (plain HTML and JavaScript, nothing fetched from elsewhere)."""
    return resources.files("tlac.human").joinpath("page.html").read_text(encoding="utf-8")


def parse_message(text: Any, n_actions: int) -> tuple[dict[str, Any] | None, str, str]:
    """A message from the page, checked: ``(message, "", "")``, or ``(None, reason, why)``
    for one that is refused (``reason`` one of :data:`MESSAGE_REASONS`, ``why`` in words).

    >>> parse_message('{"type": "answer", "id": 3, "action": 1}', 6)
    ({'type': 'answer', 'id': 3, 'action': 1}, '', '')
    >>> parse_message('{"type": "answer", "id": 3, "action": 6}', 6)[1:]
    ('bad value', 'action 6 is not one of the 6 actions')
    >>> parse_message('{"type": "answer", "id": 3, "action": true}', 6)[1:]
    ('bad value', 'action must be an integer')
    """
    if not isinstance(text, str):
        return None, "not text", "not a text message"
    if len(text) > MAX_MESSAGE:
        return None, "too long", f"longer than {MAX_MESSAGE} bytes"
    try:
        msg = json.loads(text)
    except (ValueError, RecursionError):
        return None, "not JSON", "not JSON"
    if not isinstance(msg, dict):
        return None, "not an object", "not a JSON object"
    kind = msg.get("type")
    if not isinstance(kind, str) or kind not in MESSAGE_FIELDS:
        return None, "unknown type", f"unknown type {str(kind)[:20]!r}"
    if set(msg) != MESSAGE_FIELDS[kind]:
        expected = sorted(MESSAGE_FIELDS[kind])
        return None, "fields", f"{kind}: fields {sorted(msg)[:6]} (expected {expected})"
    if kind == "answer":
        for key in ("id", "action"):
            if not isinstance(msg[key], int) or isinstance(msg[key], bool):
                return None, "bad value", f"{key} must be an integer"
        if not 0 <= msg["action"] < n_actions:
            why = f"action {msg['action']} is not one of the {n_actions} actions"
            return None, "bad value", why
    if kind == "takeover" and not isinstance(msg["on"], bool):
        return None, "bad value", "on must be true or false"
    return msg, "", ""


class Refusals:
    """Refused requests and messages: counted by reason (:data:`REQUEST_REASONS`,
    :data:`MESSAGE_REASONS`: a fixed set, whatever the page sends), logged with their detail
    without a traceback."""

    def __init__(self) -> None:
        self.counts: Counter[str] = Counter()
        self.total = 0

    def refuse(self, reason: str, why: str) -> None:
        """Count a refusal under ``reason`` and log ``why`` (the first few in full)."""
        request = reason in REQUEST_REASONS
        if not request and reason not in MESSAGE_REASONS:
            raise ValueError(f"not a reason for a refusal: {reason!r}")
        self.total += 1
        self.counts[reason] += 1
        if self.total <= LOGGED_IN_FULL:
            what = "a request" if request else "a message from the page"
            LOG.warning("tlac teach: refused %s: %s", what, why)
        elif self.total % 1000 == 0:
            LOG.warning("tlac teach: %d requests and messages refused so far", self.total)


class Outbox:
    """The messages waiting to go to one page, at most ``size``: a page that reads nothing
    makes the oldest progress report give way to a new message; with none waiting, the oldest
    message other than a question; a question gives way only to a box of questions. Used from
    the event loop's thread only (:meth:`put` through ``call_soon_threadsafe``).

    >>> box = Outbox(2)
    >>> for kind in ("question", "progress", "question"):
    ...     box.put({"type": kind})
    >>> [m["type"] for m in box.items]
    ['question', 'question']
    """

    def __init__(self, size: int = OUTBOX):
        self.size = size
        self.items: collections.deque[dict[str, Any]] = collections.deque()
        self._ready = asyncio.Event()

    def put(self, message: dict[str, Any]) -> None:
        if len(self.items) >= self.size:
            self._drop_one()
        self.items.append(message)
        self._ready.set()

    def _drop_one(self) -> None:
        """The oldest progress report; else the oldest message but a question; else the oldest
        question."""
        for gives_way in (lambda kind: kind == "progress", lambda kind: kind != "question"):
            for i, waiting in enumerate(self.items):
                if gives_way(waiting.get("type")):
                    del self.items[i]
                    return
        self.items.popleft()

    async def get(self) -> dict[str, Any]:
        while not self.items:
            self._ready.clear()
            await self._ready.wait()
        return self.items.popleft()


def _header(scope: dict[str, Any], name: bytes) -> str | None:
    """The first value of a request header, or None."""
    for key, value in scope.get("headers") or ():
        if key.lower() == name:
            return value.decode("latin-1")
    return None


def allowed_hosts(port: int) -> set[str]:
    """The ``Host`` headers the page's server answers: the loopback address by number or by
    name, with the port (without it too for port 80, where browsers leave it out)."""
    hosts = {f"{HOST}:{port}", f"localhost:{port}"}
    if port == 80:
        hosts |= {HOST, "localhost"}
    return hosts


def check_request(scope: dict[str, Any], token: bytes) -> tuple[str, str]:
    """Why an HTTP request or WebSocket handshake is refused, ``(reason, why)`` (``reason``
    one of :data:`REQUEST_REASONS`), or ``("", "")`` when it is let in: the token, the
    ``Host`` header, and a handshake's ``Origin``."""
    kind = scope["type"]
    query = parse_qs(scope.get("query_string", b"").decode("latin-1"))
    given = query.get("token", [""])[0].encode("latin-1", "replace")
    if not hmac.compare_digest(given, token):
        return f"{kind} token", f"{kind}: wrong or missing token"
    server = scope.get("server")
    port = server[1] if server and len(server) > 1 else None
    host = _header(scope, b"host")
    if not isinstance(port, int) or host is None or host.lower() not in allowed_hosts(port):
        return (
            f"{kind} Host",
            f"{kind} Host: {str(host)[:60]!r} is not {HOST}:{port} or localhost:{port} "
            "(a DNS-rebinding page?)",
        )
    origin = _header(scope, b"origin")
    if kind == "websocket" and origin is not None and origin.lower() != f"http://{host.lower()}":
        return (
            f"{kind} Origin",
            f"{kind} Origin: {origin[:60]!r} is not the page's own, http://{host[:60]} "
            "(a cross-site page?)",
        )
    return "", ""


class TokenGate:
    """ASGI middleware: every HTTP request and WebSocket handshake must carry the token and
    name the page's own host (and, for a handshake, its origin): :func:`check_request`."""

    def __init__(self, app: Any, token: str, refusals: Refusals):
        self.app, self.token, self.refusals = app, token.encode(), refusals

    async def __call__(self, scope: dict[str, Any], receive: Any, send: Any) -> None:
        if scope["type"] in ("http", "websocket"):
            reason, why = check_request(scope, self.token)
            if reason:
                self.refusals.refuse(reason, why)
                if scope["type"] == "http":
                    said = "wrong or missing token" if reason == "http token" else "wrong Host"
                    await PlainTextResponse(f"forbidden: {said}", 403)(scope, receive, send)
                else:  # close before accepting: the handshake is refused (HTTP 403)
                    message = await receive()
                    if message["type"] == "websocket.connect":
                        await send({"type": "websocket.close", "code": 1008})
                return
        await self.app(scope, receive, send)


class TokenBucket:
    """At most ``rate`` a second on average, ``burst`` at once."""

    def __init__(self, rate: float = RATE, burst: int = BURST):
        self.rate, self.burst = rate, float(burst)
        self.tokens, self.time = float(burst), time.monotonic()

    def take(self) -> bool:
        now = time.monotonic()
        self.tokens = min(self.burst, self.tokens + (now - self.time) * self.rate)
        self.time = now
        if self.tokens < 1.0:
            return False
        self.tokens -= 1.0
        return True


def make_app(desk: Desk, token: str, refusals: Refusals | None = None) -> Any:
    """The page's ASGI application: ``/`` the page, ``/ws`` its WebSocket; every request
    through :class:`TokenGate`."""
    refusals = refusals or Refusals()
    n_actions = len(desk.action_names)

    async def page(request: Any) -> Response:
        return HTMLResponse(
            page_html(),
            headers={
                "Cache-Control": "no-store",
                "Referrer-Policy": "no-referrer",
                "X-Frame-Options": "DENY",
                "Content-Security-Policy": "default-src 'none'; img-src data:; "
                "style-src 'unsafe-inline'; script-src 'unsafe-inline'; connect-src 'self' "
                "ws://127.0.0.1:* ws://localhost:*; frame-ancestors 'none'",
            },
        )

    async def socket(websocket: WebSocket) -> None:
        await websocket.accept()
        loop = asyncio.get_running_loop()
        outbox = Outbox()

        def send(message: dict[str, Any]) -> None:  # from any thread
            loop.call_soon_threadsafe(outbox.put, message)

        async def sender() -> None:
            while True:
                message = await outbox.get()
                await websocket.send_text(json.dumps(message))

        key = desk.subscribe(send)
        task = asyncio.create_task(sender())
        bucket = TokenBucket()
        try:
            while True:
                event = await websocket.receive()
                if event["type"] == "websocket.disconnect":
                    break
                if not bucket.take():
                    refusals.refuse("flood", "flood: over the rate limit")
                    continue
                message, reason, why = parse_message(event.get("text"), n_actions)
                if message is None:
                    refusals.refuse(reason, why)
                    continue
                handle(message)
        except (WebSocketDisconnect, RuntimeError, OSError):
            pass
        finally:
            desk.unsubscribe(key)
            task.cancel()

    def handle(message: dict[str, Any]) -> None:
        kind = message["type"]
        if kind == "answer":
            if not desk.answer(message["id"], message["action"]):
                refusals.refuse("not pending", f"answer: question {message['id']} is not pending")
        elif kind == "takeover":
            desk.request_takeover(message["on"])
        else:
            desk.here()

    app = Starlette(routes=[Route("/", page), WebSocketRoute("/ws", socket)])
    return TokenGate(app, token, refusals)


class PageServer:
    """uvicorn serving :func:`make_app` in a daemon thread on 127.0.0.1:``port`` (0: a free
    port). :meth:`start` returns once it listens; :attr:`url` carries the token."""

    def __init__(self, desk: Desk, port: int = 0, token: str | None = None):
        if not isinstance(port, int) or not 0 <= port <= 65535:
            raise ConfigError(f"--port must be a port number in [0, 65535], got {port!r}")
        self.desk, self.port = desk, port
        self.token = token or new_token()
        self.refusals = Refusals()
        self.app = make_app(desk, self.token, self.refusals)
        self._server: Any = None
        self._thread: threading.Thread | None = None

    @property
    def url(self) -> str:
        return f"http://{HOST}:{self.port}/?token={self.token}"

    def start(self, wait: float = 15.0) -> str:
        import uvicorn

        config = uvicorn.Config(
            self.app,
            host=HOST,
            port=self.port,
            log_level="error",
            access_log=False,
            lifespan="off",
            ws_max_size=16 * MAX_MESSAGE,
        )
        self._server = uvicorn.Server(config)
        self._server.install_signal_handlers = lambda: None  # Ctrl-C is the run's (older uvicorn)
        self._thread = threading.Thread(target=self._serve, name="tlac-teach-page", daemon=True)
        self._thread.start()
        deadline = time.monotonic() + wait
        while not self._server.started:
            if not self._thread.is_alive() or time.monotonic() > deadline:
                self.stop()  # no server thread outlives the refusal
                raise ConfigError(
                    f"tlac teach: the page's server could not listen on {HOST}:{self.port} "
                    "(is the port in use? give another with --port, or 0 for a free one)"
                )
            time.sleep(0.02)
        sockets = self._server.servers[0].sockets
        self.port = int(sockets[0].getsockname()[1])
        return self.url

    def _serve(self) -> None:
        with contextlib.suppress(SystemExit):  # uvicorn exits when it cannot bind
            self._server.run()

    def stop(self) -> None:
        if self._server is not None:
            self._server.should_exit = True
        if self._thread is not None:
            self._thread.join(timeout=5.0)
