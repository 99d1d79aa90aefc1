"""`web.viser_compat` against the installed viser: a WebSocket client's request path reaches
the viewer, which turns the proxy's ticket into the user's session."""

from __future__ import annotations

import asyncio
import time
from types import SimpleNamespace
from typing import Any

import pytest
import viser
import websockets
from websockets.typing import Subprotocol

from tests.web.memsite import grid_site
from web.roles import Session
from web.viewer import TICKET_PARAM, Viewer
from web.viser_compat import ViserCompatError, check_viser, request_path

SUBPROTOCOL = Subprotocol(f"viser-v{viser.__version__}")


def connect_and_wait(port: int, path: str, until: Any, timeout_s: float = 10.0) -> None:
    """Open a WebSocket to viser at `path`, say hello as a browser does (viser registers a
    client on its first camera message), keep it open until `until()` is true."""
    import msgspec
    from viser import _messages  # the browser's side of viser's protocol (test only)

    cam = _messages.ViewerCameraMessage(
        (1.0, 0.0, 0.0, 0.0), (0.0, -8.0, 6.0), 1.0, 0.01, 100.0, 800, 1280,
        (3.0, 2.4, 1.0), (0.0, 0.0, 1.0),
    )  # fmt: skip
    hello = msgspec.msgpack.encode(cam.as_serializable_dict())

    async def run() -> None:
        async with websockets.connect(
            f"ws://127.0.0.1:{port}{path}", subprotocols=[SUBPROTOCOL], max_size=None
        ) as ws:
            await ws.send(hello)
            deadline = time.monotonic() + timeout_s
            while not until():
                if time.monotonic() > deadline:
                    raise AssertionError("the viewer did not see the client in time")
                await asyncio.sleep(0.02)

    asyncio.run(run())


def test_request_path_of_a_live_client_carries_its_query() -> None:
    server = viser.ViserServer("127.0.0.1", 0, verbose=False)
    seen: dict[int, str | None] = {}
    try:
        check_viser(server)
        server.on_client_connect(lambda c: seen.update({c.client_id: request_path(server, c)}))
        connect_and_wait(server.get_port(), "/?irloc_ticket=abc&x=1", lambda: bool(seen))
        assert list(seen.values()) == ["/?irloc_ticket=abc&x=1"]
        assert request_path(server, 10_000) is None  # not connected
    finally:
        server.stop()


def test_a_viser_without_the_connection_table_is_a_clear_error() -> None:
    fake: Any = SimpleNamespace(_websock_server=SimpleNamespace())
    with pytest.raises(ViserCompatError, match="_live_connections is gone"):
        request_path(fake, 1)
    with pytest.raises(ViserCompatError, match=r"update web/viser_compat\.py"):
        check_viser(SimpleNamespace())  # type: ignore[arg-type]
    odd: Any = SimpleNamespace(
        _websock_server=SimpleNamespace(
            _live_connections={1: SimpleNamespace(request=SimpleNamespace(path=None))}
        )
    )
    with pytest.raises(ViserCompatError, match="no text `path`"):
        request_path(odd, 1)


def test_the_ticket_in_the_websocket_url_gives_the_browser_its_role() -> None:
    viewer = Viewer(grid_site())
    viewer.start()
    try:
        admin = Session("admin", "viewer:key:7")
        ticket = viewer.issue_ticket(admin)
        sessions: list[Session] = []

        def found() -> bool:
            sessions[:] = [s for cid in range(64) if (s := viewer.session_of(cid)) is not None]
            return bool(sessions)

        connect_and_wait(viewer.port, f"/?{TICKET_PARAM}={ticket}", found)
        assert sessions == [admin]
    finally:
        viewer.stop()


def refused(port: int, path: str, origin: str | None = None) -> tuple[int, str, int]:
    """Connect to viser directly as a browser would; (close code, reason, messages got)."""
    import msgspec
    from viser import _messages

    cam = _messages.ViewerCameraMessage(
        (1.0, 0.0, 0.0, 0.0), (0.0, -8.0, 6.0), 1.0, 0.01, 100.0, 800, 1280,
        (3.0, 2.4, 1.0), (0.0, 0.0, 1.0),
    )  # fmt: skip

    async def run() -> tuple[int, str, int]:
        got = 0
        async with websockets.connect(
            f"ws://127.0.0.1:{port}{path}", subprotocols=[SUBPROTOCOL], max_size=None,
            origin=origin,  # type: ignore[arg-type]
        ) as ws:  # fmt: skip
            try:
                await ws.send(msgspec.msgpack.encode(cam.as_serializable_dict()))
                while True:
                    await asyncio.wait_for(ws.recv(), 5)
                    got += 1
            except websockets.ConnectionClosed as exc:
                assert exc.rcvd is not None
                return exc.rcvd.code, exc.rcvd.reason, got

    return asyncio.run(run())


def test_viser_own_port_refuses_everyone_but_the_proxy() -> None:
    viewer = Viewer(grid_site())
    viewer.start()
    try:
        # another process on the host, no ticket: refused before any scene is sent
        code, reason, got = refused(viewer.port, "/")
        assert (code, got) == (1008, 0) and "/viewer/" in reason
        # a spent or forged ticket: the same
        ticket = viewer.issue_ticket(Session("admin", "viewer:key:7"))
        assert refused(viewer.port, f"/?{TICKET_PARAM}=forged")[::2] == (1008, 0)
        # a web page in a browser on the host carries an Origin: refused even with a ticket
        code, _, got = refused(viewer.port, f"/?{TICKET_PARAM}={ticket}", "http://evil.example")
        assert (code, got) == (1008, 0)
        assert not any(viewer.session_of(cid) for cid in range(64))
        # the proxy's way in (a live ticket, no Origin) still works, once
        connect_and_wait(viewer.port, f"/?{TICKET_PARAM}={ticket}",
                         lambda: any(viewer.session_of(c) for c in range(64)))  # fmt: skip
        assert refused(viewer.port, f"/?{TICKET_PARAM}={ticket}")[::2] == (1008, 0)  # spent
    finally:
        viewer.stop()
