"""API keys on requests: `Authorization: Bearer <key>` (or `?token=<key>` where a browser
cannot set headers: WebSocket, EventSource), and the role each endpoint needs.

Roles are ordered viewer < operator < admin: viewer reads; operator also switches LEDs,
relocalizes and records; admin also edits the map, keys and configuration.
"""

from __future__ import annotations

from collections.abc import Awaitable, Callable
from dataclasses import dataclass
from typing import Annotated

from fastapi import Depends, HTTPException, status
from fastapi.security import HTTPAuthorizationCredentials, HTTPBearer
from starlette.requests import HTTPConnection

from server.models import Role

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


def authenticate(conn: HTTPConnection) -> Principal | None:
    """The caller's principal, or None for a missing, unknown or revoked key."""
    token = token_of(conn)
    if token is None:
        return None
    found = conn.app.state.services.keys.role_of(token)
    return None if found is None else Principal(found[0], found[1])


def require(role: Role) -> Callable[..., Awaitable[Principal]]:
    """A dependency admitting keys of `role` or higher: 401 without a valid key, 403 when
    the key's role is too low."""

    async def dependency(
        conn: HTTPConnection,
        _cred: Annotated[HTTPAuthorizationCredentials | None, Depends(_bearer)] = None,
    ) -> Principal:
        principal = authenticate(conn)
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
