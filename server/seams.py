"""What the server expects of the parts it is handed (docs/architecture.md, "Seams").

The server never imports the viewer: `irloc serve` (irloc/serve.py) builds one and hands it
to `server.main.create_app(settings, viewer)`; anything with these methods will do.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Protocol

from fastapi import APIRouter
from starlette.requests import HTTPConnection

from server.auth import Principal

if TYPE_CHECKING:
    from live.services import SiteServices

Authenticate = Callable[[HTTPConnection], Principal | None]
"""`server.auth.authenticate`: a request or WebSocket -> its key's principal, or None."""


class ViewerApp(Protocol):
    """A viewer served by the API (web.viewer.Viewer).

    The app includes `router(authenticate)` when it is built, calls `start(services)` in its
    lifespan once the services run (from a worker thread: it may block), and `stop()` at
    shutdown (from a worker thread too: the viewer may wait on coroutines on the loop).
    """

    def router(self, authenticate: Authenticate) -> APIRouter: ...

    def start(self, services: SiteServices) -> None: ...

    def stop(self) -> None: ...
