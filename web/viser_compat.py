"""The one place the viewer reaches into viser's internals: a client's WebSocket request path.

viser 1.1 offers no public way to read the HTTP request a browser's WebSocket was opened
with, and the viewer needs its query string (the proxy's one-time ticket naming the user's
role, `web.viewer.TICKET_PARAM`). viser 1.1 keeps each live connection (a `websockets`
`ServerConnection`, whose public `request.path` holds the path and query) in
`server._websock_server._live_connections[client_id]`. Only `request_path`,
`request_header` and `refuse` read it; when a viser release moves it they raise
`ViserCompatError` saying so, the viewer logs that and refuses every browser (safe failure),
and `tests/web/test_viser_compat.py` fails against the real viser.
"""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import Callable
from typing import Any

import viser


class ViserCompatError(RuntimeError):
    """The installed viser no longer exposes what `request_path` reads."""


def _live_connections(server: viser.ViserServer) -> dict[int, Any]:
    try:
        conns = server._websock_server._live_connections
    except AttributeError:
        conns = None
    if not isinstance(conns, dict):
        raise ViserCompatError(
            f"viser {viser.__version__}: ViserServer._websock_server._live_connections is gone "
            "(written for viser 1.1): the viewer cannot read the proxy's ticket, so every "
            "browser is read-only; update web/viser_compat.py"
        )
    return conns


def check_viser(server: viser.ViserServer) -> None:
    """Raise `ViserCompatError` now (at start-up) when `request_path` cannot work."""
    _live_connections(server)


def request_path(server: viser.ViserServer, client: int | viser.ClientHandle) -> str | None:
    """The path and query string of a connected client's WebSocket handshake request.

    Args:
        server: a started viser server.
        client: a connected client, or its `client_id`.

    Returns:
        e.g. "/?irloc_ticket=abc", or None when that client is no longer connected.

    Raises:
        ViserCompatError: when the installed viser keeps its connections elsewhere.
    """
    client_id = client if isinstance(client, int) else client.client_id
    conn = _live_connections(server).get(client_id)
    if conn is None:
        return None
    request = getattr(conn, "request", None)
    path = getattr(request, "path", None)
    if request is not None and not isinstance(path, str):
        raise ViserCompatError(
            f"viser {viser.__version__}: a live connection's request has no text `path` "
            f"({type(conn).__name__}); update web/viser_compat.py"
        )
    return path


def request_header(server: viser.ViserServer, client: viser.ClientHandle, name: str) -> str | None:
    """A header of a connected client's WebSocket handshake (e.g. `Origin`), or None."""
    conn = _live_connections(server).get(client.client_id)
    headers = getattr(getattr(conn, "request", None), "headers", None)
    if headers is None:
        return None
    value = headers.get(name)
    return value if isinstance(value, str) else None


def refuse(server: viser.ViserServer, client: viser.ClientHandle, reason: str) -> None:
    """Close a client's WebSocket with code 1008 and `reason`. Called from viser's connect
    callback (on viser's loop), the close is queued before viser starts sending the scene,
    so a refused browser receives nothing."""
    conn = _live_connections(server).get(client.client_id)
    if conn is None:
        return
    closing = conn.close(1008, reason[:120])
    try:
        asyncio.get_running_loop().create_task(closing)
    except RuntimeError:  # not on viser's loop: hand it over
        loop = getattr(server._websock_server, "_background_event_loop", None)
        if loop is None:
            closing.close()
            return
        with contextlib.suppress(RuntimeError):
            asyncio.run_coroutine_threadsafe(closing, loop)


Admit = Callable[[str | None, str | None], str | None]
"""(handshake path and query, Origin header) -> None to admit, or the reason to refuse."""


def guard_connections(server: viser.ViserServer, admit: Admit) -> None:
    """Decide on every WebSocket at viser's own connection layer, before viser sends it
    anything: a refused one is closed with 1008 and the reason, and gets no scene. (viser's
    `on_client_connect` callbacks run on a worker thread, after the scene has started to
    flow; its connection layer's callbacks run first, on its loop.)"""
    infra = getattr(server, "_websock_server", None)
    register = getattr(infra, "on_client_connect", None)
    if register is None:
        raise ViserCompatError(
            f"viser {viser.__version__}: ViserServer._websock_server.on_client_connect is "
            "gone: the viewer cannot refuse connections on viser's port; update "
            "web/viser_compat.py"
        )

    def check(handle: Any) -> None:
        conn = _live_connections(server).get(handle.client_id)
        request = getattr(conn, "request", None)
        headers = getattr(request, "headers", None)
        origin = headers.get("Origin") if headers is not None else None
        reason = admit(getattr(request, "path", None), origin)
        if reason is not None and conn is not None:
            asyncio.get_running_loop().create_task(conn.close(1008, reason[:120]))

    register(check)


def disable_share(server: viser.ViserServer, on_refused: Callable[[int], None]) -> None:
    """Refuse viser's "Share" request from every browser: viser would open a public tunnel
    to its own port, which has no key check (only the keyed `/viewer/` proxy may reach it).

    viser 1.1 registers `ShareUrlRequest` and `ShareUrlDisconnect` handlers on its connection
    layer; they are replaced by one that only reports the attempt (`on_refused(client_id)`),
    and `request_share_url` itself is made to refuse, so a crafted client that sends the
    message anyway opens nothing. (The button is hidden by `configure_theme`.)

    Raises:
        ViserCompatError: when the installed viser keeps its handlers elsewhere.
    """
    from viser import _messages

    infra = getattr(server, "_websock_server", None)
    handlers = getattr(infra, "_incoming_handlers", None)
    unregister = getattr(infra, "unregister_handler", None)
    register = getattr(infra, "register_handler", None)
    if not isinstance(handlers, dict) or unregister is None or register is None:
        raise ViserCompatError(
            f"viser {viser.__version__}: ViserServer._websock_server's message handlers are "
            "gone: the viewer cannot refuse viser's share tunnel; update web/viser_compat.py"
        )
    for message in (_messages.ShareUrlRequest, _messages.ShareUrlDisconnect):
        if message in handlers:
            unregister(message)

    def refused(client_id: int, _: object) -> None:
        on_refused(client_id)

    register(_messages.ShareUrlRequest, refused)

    def no_share(verbose: bool = True) -> str | None:
        raise RuntimeError("irloc: viser's share tunnel is disabled (open /viewer/ with a key)")

    server.request_share_url = no_share  # type: ignore[method-assign]
