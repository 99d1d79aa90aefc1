"""When a long-lived stream (pose WebSocket, event stream) must end before its client leaves:
its key was revoked (through the API: at once; by `irloc keys revoke` in another process:
within about a second), or the server is shutting down (`draining`).
"""

from __future__ import annotations

import asyncio
import threading
from collections.abc import Callable
from typing import Any, TypeVar

from starlette.requests import HTTPConnection

from server.auth import Principal, token_of

T = TypeVar("T")
POLL_S = 0.2
"""How often a stream looks at the in-process revocations and the shutdown flag, seconds."""
RECHECK_S = 1.0
"""How often it checks its key again (cache, else the database), seconds."""
SHUTTING_DOWN = "the server is shutting down"
KEY_REVOKED = "the API key was revoked"


def _flag(app: Any, name: str, make: Callable[[], T]) -> T:
    """`app.state.<name>`, made with `make()` on first use."""
    flag: T | None = getattr(app.state, name, None)
    if flag is None:
        flag = make()
        setattr(app.state, name, flag)
    return flag


def draining(app: Any) -> asyncio.Event:
    """The app's shutdown flag: set when the server starts shutting down (`server.shutdown`)."""
    return _flag(app, "draining", asyncio.Event)


def stopping(app: Any) -> threading.Event:
    """The app's shutdown flag for work on threads (set with `draining`)."""
    return _flag(app, "stopping", threading.Event)


async def stream_end(conn: HTTPConnection, principal: Principal) -> str:
    """Wait until the stream of `conn` must end; returns why (`KEY_REVOKED`, `SHUTTING_DOWN`)."""
    keys = conn.app.state.services.keys
    token = token_of(conn)
    flag = draining(conn.app)
    loop = asyncio.get_running_loop()
    next_check = loop.time() + RECHECK_S
    while True:
        try:
            await asyncio.wait_for(flag.wait(), POLL_S)
            return SHUTTING_DOWN
        except TimeoutError:
            pass
        if keys.is_revoked_here(principal.key_id):
            return KEY_REVOKED
        if loop.time() >= next_check:
            next_check = loop.time() + RECHECK_S
            if token is None or await keys.role_of_async(token) is None:
                return KEY_REVOKED
