"""The pose WebSocket and the event stream (SSE)."""

from __future__ import annotations

import json
import time
from typing import Any

import numpy as np
import pytest
from starlette.websockets import WebSocketDisconnect

from live.poses import PoseUpdate
from tests.server.conftest import LM, Api


def _pose(robot: str, i: int) -> PoseUpdate:
    return PoseUpdate(
        robot,
        1_000_000 * i,
        "landmark",
        0.1 * i,
        -0.2 * i,
        0.05 * i,
        np.diag([1e-4, 1e-4, 1e-3]),
        (11, 12),
    )


def _receive(ws: object, n: int) -> list[dict[str, Any]]:
    got: list[dict[str, Any]] = []
    while len(got) < n:
        got += json.loads(ws.receive_text())  # type: ignore[attr-defined]
    return got


def test_ws_streams_poses_in_order_with_values(api: Api) -> None:
    with api.client.websocket_connect("/api/v1/poses/ws", headers=api.h("viewer")) as ws:
        for i in range(20):
            api.services.poses.publish(_pose("r1", i))
        got = _receive(ws, 20)
    assert [p["t_ns"] for p in got] == [1_000_000 * i for i in range(20)]
    np.testing.assert_allclose([got[7]["x"], got[7]["y"], got[7]["theta"]], [0.7, -1.4, 0.35])
    np.testing.assert_allclose(got[7]["covariance"], np.diag([1e-4, 1e-4, 1e-3]))
    assert got[7]["landmark_ids"] == [11, 12] and got[7]["mode"] == "landmark"


def test_ws_filters_by_robot_and_accepts_a_token_parameter(api: Api) -> None:
    url = f"/api/v1/poses/ws?robot=r2&robot=r3&token={api.keys['viewer']}"
    with api.client.websocket_connect(url) as ws:
        for i in range(9):
            api.services.poses.publish(_pose(f"r{1 + i % 3}", i))
        got = _receive(ws, 6)
    assert [p["robot"] for p in got] == ["r2", "r3"] * 3


def test_ws_without_key_is_closed(api: Api) -> None:
    with (
        pytest.raises(WebSocketDisconnect) as exc,
        api.client.websocket_connect("/api/v1/poses/ws") as ws,
    ):
        ws.receive_text()
    assert exc.value.code == 1008


def test_client_gone_after_disconnect(api: Api) -> None:
    fanout = api.client.app.state.pose_fanout  # type: ignore[attr-defined]
    with api.client.websocket_connect("/api/v1/poses/ws", headers=api.h("viewer")) as ws:
        api.services.poses.publish(_pose("r1", 1))
        _receive(ws, 1)
        assert len(fanout.clients) == 1
    for _ in range(100):
        if not fanout.clients:
            break
        time.sleep(0.01)
    assert fanout.clients == []


def test_sse_streams_map_changes(api: Api) -> None:
    c = api.client
    with c.stream("GET", "/api/v1/events/stream?limit=2", headers=api.h("viewer")) as r:
        assert r.headers["content-type"].startswith("text/event-stream")
        c.post("/api/v1/landmarks", json=LM, headers=api.h("admin"))
        c.delete("/api/v1/landmarks/11?confirm=true", headers=api.h("admin"))
        text = "".join(r.iter_text())
    events = [json.loads(line[6:]) for line in text.splitlines() if line.startswith("data: ")]
    assert [e["kind"] for e in events] == ["map_changed", "map_changed"]
    assert [e["data"]["count"] for e in events] == [1, 0]
    listed = c.get("/api/v1/events", headers=api.h("viewer")).json()
    assert [e["id"] for e in listed] == [events[1]["id"], events[0]["id"]]
