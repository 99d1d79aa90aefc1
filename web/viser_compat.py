"""The one place the viewer reaches into viser's internals: a client's WebSocket request path.

viser 1.1 offers no public way to read the HTTP request a browser's WebSocket was opened
with, and the viewer needs its query string (the proxy's one-time ticket naming the user's
role, `web.viewer.TICKET_PARAM`). viser 1.1 keeps each live connection (a `websockets`
`ServerConnection`, whose public `request.path` holds the path and query) in
`server._websock_server._live_connections[client_id]`. Only `request_path` reads it; when a
viser release moves it, `request_path` raises `ViserCompatError` saying so, the viewer logs
that and treats every browser as read-only (safe failure), and `tests/web/test_viser_compat.py`
fails against the real viser.
"""

from __future__ import annotations

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
