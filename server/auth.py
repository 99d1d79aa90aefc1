"""API keys on requests: `Authorization: Bearer <key>` (or `?token=<key>` where a browser
cannot set headers: WebSocket, EventSource), and the role each endpoint needs.

Roles are ordered viewer < operator < admin: viewer reads; operator also switches LEDs,
relocalizes and records; admin also edits the map, keys and configuration.

Keys are checked by `authenticate_async` on the event loop: cached answers at once, a
database lookup on a worker thread (`store.keys.KeyStore.role_of_async`), bad keys
counted per client address (`server.throttle`: past the budget, 429 / close 1008 before any
lookup). A WebSocket that is refused is accepted and then closed with code 1008 and the reason
(`refuse_websocket`), so a client learns why.
"""

from __future__ import annotations

import math
from collections.abc import Awaitable, Callable
from dataclasses import dataclass
from typing import Annotated

from fastapi import Depends, HTTPException, WebSocket, status
from fastapi.security import HTTPAuthorizationCredentials, HTTPBearer
from starlette.requests import HTTPConnection

from server.throttle import BadKeyThrottle
from store.models import Role

ROLE_RANK: dict[str, int] = {"viewer": 0, "operator": 1, "admin": 2}
_bearer = HTTPBearer(auto_error=False, description="an API key from `irloc keys create`")


@dataclass(frozen=True)
class Principal:
    """Who is calling: the key's database id and role."""

    key_id: int
    role: Role

    @property
    def actor(self) -> str:
        """How the audit log names this caller."""
        return f"key:{self.key_id}"

    def allows(self, role: Role) -> bool:
        return ROLE_RANK[self.role] >= ROLE_RANK[role]


def token_of(conn: HTTPConnection) -> str | None:
    """The key sent with a request or WebSocket: bearer header first, then `token` query."""
    header = conn.headers.get("authorization", "")
    scheme, _, value = header.partition(" ")
    if scheme.lower() == "bearer" and value.strip():
        return value.strip()
    return conn.query_params.get("token") or None


class TooManyBadKeysError(Exception):
    """The caller's address sent too many bad keys (HTTP 429, WebSocket close 1008)."""

    def __init__(self, retry_after_s: float) -> None:
        super().__init__(
            f"too many requests with bad API keys from this address: retry in "
            f"{math.ceil(retry_after_s)} s"
        )
        self.retry_after_s = retry_after_s


def address_of(conn: HTTPConnection) -> str:
    """The client's address (the unit of the bad-key throttle)."""
    return conn.client.host if conn.client is not None else "unknown"


def throttle_of(conn: HTTPConnection) -> BadKeyThrottle:
    """The app's bad-key throttle (made on first use)."""
    state = conn.app.state
    throttle: BadKeyThrottle | None = getattr(state, "key_throttle", None)
    if throttle is None:
        throttle = state.key_throttle = BadKeyThrottle()
    return throttle


def authenticate(conn: HTTPConnection) -> Principal | None:
    """The caller's principal, or None for a missing, unknown or revoked key (synchronous:
    may read the database on the calling thread; the routes use `authenticate_async`)."""
    token = token_of(conn)
    if token is None:
        return None
    found = conn.app.state.services.keys.role_of(token)
    return None if found is None else Principal(found[0], found[1])


async def authenticate_async(conn: HTTPConnection) -> Principal | None:
    """The caller's principal, or None for a missing, unknown or revoked key.

    Raises:
        TooManyBadKeysError: the caller's address has spent its bad-key budget (nothing looked up).
    """
    token = token_of(conn)
    if token is None:
        return None
    keys = conn.app.state.services.keys
    known = keys.cached(token)
    throttle = throttle_of(conn)
    address = address_of(conn)
    if known is False:
        wait_s = throttle.retry_after_s(address)
        if wait_s > 0:
            raise TooManyBadKeysError(wait_s)
        known = await keys.role_of_async(token)
    if known is None or known is False:
        throttle.failed(address)
        return None
    return Principal(known[0], known[1])


async def refuse_websocket(ws: WebSocket, reason: str) -> None:
    """Refuse a WebSocket with close code 1008 and `reason` (accepted first: a close before
    the handshake would reach the client as a bare HTTP 403)."""
    await ws.accept()
    await ws.close(code=status.WS_1008_POLICY_VIOLATION, reason=reason[:120])


async def websocket_principal(ws: WebSocket, role: Role) -> Principal | None:
    """The principal of a WebSocket of at least `role`; else refuse it (1008) and None."""
    try:
        principal = await authenticate_async(ws)
    except TooManyBadKeysError as exc:
        await refuse_websocket(ws, str(exc))
        return None
    if principal is None:
        await refuse_websocket(ws, "a valid API key is required (Bearer header or ?token=)")
        return None
    if not principal.allows(role):
        await refuse_websocket(ws, f"this needs the {role} role; the key is {principal.role}")
        return None
    return principal


def require(role: Role) -> Callable[..., Awaitable[Principal]]:
    """A dependency admitting keys of `role` or higher: 401 without a valid key, 403 when
    the key's role is too low."""

    async def dependency(
        conn: HTTPConnection,
        _cred: Annotated[HTTPAuthorizationCredentials | None, Depends(_bearer)] = None,
    ) -> Principal:
        try:
            principal = await authenticate_async(conn)
        except TooManyBadKeysError as exc:
            raise HTTPException(
                status.HTTP_429_TOO_MANY_REQUESTS,
                str(exc),
                headers={"Retry-After": str(math.ceil(exc.retry_after_s))},
            ) from None
        if principal is None:
            raise HTTPException(
                status.HTTP_401_UNAUTHORIZED,
                "a valid API key is required (Authorization: Bearer <key>)",
                headers={"WWW-Authenticate": "Bearer"},
            )
        if not principal.allows(role):
            raise HTTPException(
                status.HTTP_403_FORBIDDEN,
                f"this needs the {role} role; the key is {principal.role}",
            )
        return principal

    return dependency


Viewer = Annotated[Principal, Depends(require("viewer"))]
Operator = Annotated[Principal, Depends(require("operator"))]
Admin = Annotated[Principal, Depends(require("admin"))]
