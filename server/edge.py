"""`EdgeGuard`: the ASGI middleware every HTTP request passes before a route reads its body.

1. A request that carries a body (`Content-Length` > 0 or chunked) to the API needs a valid
   key in its headers (`Authorization: Bearer`, or `?token=`) before one byte of the body is
   read: 401 (429 for a throttled address sending bad keys) at once, the body left unread.
2. Bodies are bounded (`body_limit`): a declared `Content-Length` over the limit is answered
   413 at once; a chunked or lying body is counted as it streams and answered 413 as soon as
   the count passes the limit (the route never sees the rest).
3. A request still reading its body when the shutdown's grace is over is answered 503
   ("the server is shutting down"), not 500 with a traceback.
4. Every answer carries `X-Frame-Options: DENY`, `X-Content-Type-Options: nosniff` and a
   Content-Security-Policy (`frame-ancestors 'none'`), so no other site frames the app.
"""

from __future__ import annotations

import asyncio
import json
import math
from dataclasses import dataclass, field

from starlette.requests import HTTPConnection
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from server.auth import TooManyBadKeysError, authenticate_async
from server.storage_errors import storage_answer
from server.stream_guard import SHUTTING_DOWN, draining

MIB = 1024 * 1024
DEFAULT_BODY_BYTES = 1 * MIB
"""A request body's limit where no route needs more (JSON edits are a few kB)."""
ROUTE_BODY_BYTES: tuple[tuple[str, str, int], ...] = (
    ("PUT", "/api/v1/map", 32 * MIB),  # a 100,000-landmark map.json is about 9 MB
    ("PUT", "/api/v1/floorplan", 25 * MIB + 4096),  # store.floorplan.MAX_BYTES
    ("POST", "/calibration/lens", 256 * MIB),  # up to 60 photos (suffix of the path)
)
"""(method, path or path suffix, limit in bytes) for the routes that take large bodies."""
SECURITY_HEADERS: tuple[tuple[bytes, bytes], ...] = (
    (b"x-frame-options", b"DENY"),
    (b"x-content-type-options", b"nosniff"),
    (b"content-security-policy", b"frame-ancestors 'none'"),
)


def same_origin(conn: HTTPConnection) -> bool:
    """Whether a browser's `Origin` (if it sent one) is this server itself: a WebSocket that
    a page of another site opens (with the user's viewer cookie) must be refused."""
    origin = conn.headers.get("origin")
    if origin is None:
        return True  # not a browser page (a script, a tool)
    host = conn.headers.get("host", "")
    _, _, rest = origin.partition("://")
    return bool(host) and rest.rstrip("/").lower() == host.lower()


def _shutting_down(scope: Scope) -> bool:
    app = scope.get("app")
    return app is not None and hasattr(app, "state") and draining(app).is_set()


class BodyTooLargeError(Exception):
    """A request body passed its limit while it was read (answered 413)."""

    def __init__(self, limit: int) -> None:
        super().__init__(f"request body larger than {limit} bytes")
        self.limit = limit


def body_limit(method: str, path: str, default: int = DEFAULT_BODY_BYTES) -> int:
    """The largest body a request of `method` to `path` may carry, bytes."""
    for m, route, limit in ROUTE_BODY_BYTES:
        if method == m and (path == route or (route.startswith("/") and path.endswith(route))):
            return limit
    return default


def _declared_length(scope: Scope) -> int | None:
    for name, value in scope.get("headers", []):
        if name == b"content-length":
            try:
                return int(value)
            except ValueError:
                return None
    return None


def _has_body(scope: Scope) -> bool:
    length = _declared_length(scope)
    if length is not None:
        return length > 0
    return any(n == b"transfer-encoding" for n, _ in scope.get("headers", []))


@dataclass
class EdgeCounters:
    """What the guard refused (for `/metrics` and the tests)."""

    too_large: int = 0
    body_without_key: int = 0
    by_status: dict[int, int] = field(default_factory=dict)


async def _answer(send: Send, status: int, detail: str, headers: list[tuple[bytes, bytes]]) -> None:
    body = json.dumps({"detail": detail}).encode()
    await send(
        {
            "type": "http.response.start",
            "status": status,
            "headers": [
                (b"content-type", b"application/json"),
                (b"content-length", str(len(body)).encode()),
                (b"connection", b"close"),
                *headers,
                *SECURITY_HEADERS,
            ],
        }
    )
    await send({"type": "http.response.body", "body": body})


class EdgeGuard:
    """See the module. `default_body_bytes`: the limit of routes not in `ROUTE_BODY_BYTES`."""

    def __init__(
        self,
        app: ASGIApp,
        default_body_bytes: int = DEFAULT_BODY_BYTES,
        counters: EdgeCounters | None = None,
    ) -> None:
        self.app = app
        self.default_body_bytes = default_body_bytes
        self.counters = counters if counters is not None else EdgeCounters()

    def _refused(self, status: int) -> None:
        self.counters.by_status[status] = self.counters.by_status.get(status, 0) + 1

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        method, path = scope["method"], scope["path"]
        limit = body_limit(method, path, self.default_body_bytes)
        declared = _declared_length(scope)
        if declared is not None and declared > limit:
            self.counters.too_large += 1
            self._refused(413)
            await _answer(send, 413, f"request body of {declared} bytes: at most {limit}", [])
            return
        if path.startswith("/api/") and _has_body(scope):
            refusal = await self._key_refusal(scope)
            if refusal is not None:
                self.counters.body_without_key += 1
                status, detail, headers = refusal
                self._refused(status)
                await _answer(send, status, detail, headers)
                return
        await self._guarded(scope, receive, send, limit)

    async def _key_refusal(self, scope: Scope) -> tuple[int, str, list[tuple[bytes, bytes]]] | None:
        conn = HTTPConnection(scope)
        try:
            principal = await authenticate_async(conn)
        except TooManyBadKeysError as exc:
            return 429, str(exc), [(b"retry-after", str(math.ceil(exc.retry_after_s)).encode())]
        except Exception as exc:  # the key could not be checked: the database failed
            answer = storage_answer(exc)
            if answer is None:
                raise
            return answer[0], answer[1], [(b"retry-after", b"5")]
        if principal is None:
            return (
                401,
                "a valid API key is required (Authorization: Bearer <key>)",
                [(b"www-authenticate", b"Bearer")],
            )
        return None

    async def _guarded(self, scope: Scope, receive: Receive, send: Send, limit: int) -> None:
        seen = 0
        started = False

        async def counted() -> Message:
            nonlocal seen
            message = await receive()
            if message["type"] == "http.request":
                seen += len(message.get("body", b""))
                if seen > limit:
                    raise BodyTooLargeError(limit)
            return message

        async def stamped(message: Message) -> None:
            nonlocal started
            if message["type"] == "http.response.start":
                started = True
                message = {**message, "headers": [*message.get("headers", []), *SECURITY_HEADERS]}
            await send(message)

        try:
            await self.app(scope, counted, stamped)
        except asyncio.CancelledError:
            # uvicorn cancels what is left once the shutdown's grace is over (a half-sent
            # upload): answer 503, as for every request refused while shutting down
            if started or not _shutting_down(scope):
                raise
            self._refused(503)
            await _answer(send, 503, SHUTTING_DOWN, [(b"retry-after", b"5")])
        except BodyTooLargeError as exc:
            self.counters.too_large += 1
            self._refused(413)
            if not started:
                await _answer(send, 413, f"request body larger than {exc.limit} bytes", [])
