"""`WS /robots/{name}/ws`: a remote robot pushing frames and wheel speeds, end to end.

The test client plays the robot: it drives a known arc, sends its wheel speeds and the
frames the virtual site renders from the true pose (with the LEDs as the gateway lit them),
and the server's localizer for it converges near the truth.
"""

from __future__ import annotations

import json
import struct
import time
from collections.abc import Iterator

import cv2
import numpy as np
import pytest

from localizer.geometry import T_world_body_from_pose
from localizer.odometry import integrate_arc
from tests.server.conftest import Api, start_api

pytestmark = pytest.mark.slow
WS = "/api/v1/robots/rem/ws"


@pytest.fixture(scope="module")
def site(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Api]:
    """The live virtual site (its simulated robot patrolling and localizing too: both ask
    for LEDs) plus a robot `rem` of source `remote` with the simulated robot's camera."""
    for api in start_api(tmp_path_factory.mktemp("remote"), scenario="paper_floor"):
        sim_name = api.services.virtual_site.robot_names[0]
        conf = api.client.get(f"/api/v1/robots/{sim_name}/config", headers=api.h("viewer"))
        body = {**conf.json(), "name": "rem", "source": "remote"}
        r = api.client.put("/api/v1/robots/rem/config", json=body, headers=api.h("admin"))
        assert r.status_code == 200, r.text
        yield api


def _frame(t_ns: int, image: np.ndarray, raw: bool = False) -> bytes:
    """A frame message: PNG, or raw 8-bit gray."""
    if raw:
        h, w = image.shape
        return struct.pack("<q", t_ns) + b"GRY8" + struct.pack("<II", w, h) + image.tobytes()
    ok, png = cv2.imencode(".png", image)
    assert ok
    return struct.pack("<q", t_ns) + png.tobytes()


def test_remote_robot_converges_near_the_truth_and_survives_a_disconnect(site: Api) -> None:
    s = site.services
    sim_name = s.virtual_site.robot_names[0]
    wheel_base = s.robots.get("rem").geometry.wheel_base
    x0, y0, th0 = s.virtual_site.true_pose(sim_name)
    v_left, v_right = 0.04, 0.05
    t0 = s.clock_ns()
    errors: list[float] = []
    modes: list[str] = []
    with site.client.websocket_connect(WS, headers=site.h("operator")) as ws:
        t_end = time.monotonic() + 90
        while time.monotonic() < t_end:
            t = s.clock_ns()
            x, y, th = (
                float(v)
                for v in integrate_arc(x0, y0, th0, v_left, v_right, (t - t0) * 1e-9, wheel_base)
            )
            ws.send_text(json.dumps({"type": "odometry", "v_left": v_left, "v_right": v_right,
                                     "t_ns": t}))  # fmt: skip
            image = s.virtual_site.render(sim_name, T_world_body_from_pose(x, y, th))
            ws.send_bytes(_frame(t, image, raw=len(modes) % 2 == 1))  # PNG and raw in turn
            answer = json.loads(ws.receive_text())
            assert answer["robot"] == "rem" and answer["t_ns"] == t
            modes.append(answer["mode"])
            if answer["mode"] == "landmark":
                errors.append(float(np.hypot(answer["x"] - x, answer["y"] - y)))
                if len(errors) >= 5:
                    break
            time.sleep(0.03)
    assert len(errors) >= 5, f"the remote robot never localized from its frames: {modes}"
    assert max(errors[-5:]) < 0.1  # metres
    mode = s.robots.mode("rem")
    time.sleep(0.2)
    r = site.client.get("/api/v1/robots/rem", headers=site.h("viewer"))
    assert r.status_code == 200 and r.json()["mode"] == mode  # closed: kept, not crashed
    kinds = [e.kind for e in s.events.recent(50) if e.robot == "rem"]
    assert kinds[0] == "robot_disconnected" and kinds[-1] == "robot_connected"


@pytest.mark.parametrize(
    ("message", "error"),
    [
        ("not json", "message is not JSON"),
        ("[1, 2]", "message must be a JSON object"),
        ('{"type": "pose"}', "type: expected 'odometry' or 'spots', got 'pose'"),
        ('{"type": "odometry", "v_left": 0.1}', "v_right must be a number"),
        ('{"type": "odometry", "v_left": 0.1, "v_right": 99}', "got 99"),
        ('{"type": "odometry", "v_left": 0.1, "v_right": 0.1, "t_ns": -5}', "t_ns: expected"),
        ('{"type": "spots", "pixels": [[1, 2, 3]]}', "pixels must have shape (N, 2)"),
        ('{"type": "spots", "pixels": [[1, 2]], "intensities": [], "areas": []}', "1 pixels"),
        ('{"type": "spots", "pixels": [["a", 2]]}', "pixels must be numbers"),
        (b"\x00" * 8 + b"not a png", "bytes after t_ns are neither a PNG/JPEG image"),
        (b"\x00" * 8 + b"GRY8" + struct.pack("<II", 4, 3) + b"\x00" * 11, "needs 12 pixel"),
        (b"\x00" * 8 + b"GR16" + struct.pack("<II", 0, 3), "empty or too large"),
        (b"\x01\x02", "8-byte t_ns then an encoded image"),
    ],
)
def test_malformed_messages_get_a_clear_error_and_the_connection_stays(
    site: Api, message: str | bytes, error: str
) -> None:
    with site.client.websocket_connect(WS, headers=site.h("operator")) as ws:
        if isinstance(message, bytes):
            ws.send_bytes(message)
        else:
            ws.send_text(message)
        assert error in json.loads(ws.receive_text())["error"]
        ws.send_text('{"type": "spots", "pixels": [], "intensities": [], "areas": []}')
        assert json.loads(ws.receive_text())["robot"] == "rem"  # still served


@pytest.mark.parametrize(
    ("path", "role", "reason"),
    [
        (WS, "viewer", "this needs the operator role"),
        ("/api/v1/robots/nobody/ws", "operator", "'nobody' is not running"),
    ],
)
def test_refused_connections_name_the_reason(site: Api, path: str, role: str, reason: str) -> None:
    from starlette.websockets import WebSocketDisconnect

    with (
        pytest.raises(WebSocketDisconnect) as exc,
        site.client.websocket_connect(path, headers=site.h(role)) as ws,
    ):
        ws.receive_text()
    assert exc.value.code == 1008 and reason in (exc.value.reason or "")


def test_a_simulated_robot_refuses_remote_frames(site: Api) -> None:
    from starlette.websockets import WebSocketDisconnect

    name = site.services.virtual_site.robot_names[0]
    site.services.runner.start_robot(site.services.robot_store.get(name))
    with (
        pytest.raises(WebSocketDisconnect) as exc,
        site.client.websocket_connect(f"/api/v1/robots/{name}/ws", headers=site.h("admin")) as ws,
    ):
        ws.receive_text()
    site.services.runner.stop_robot(name)
    assert "has source 'sim', not 'remote'" in (exc.value.reason or "")


def test_a_decompression_bomb_frame_is_refused_from_its_header(site: Api) -> None:
    import struct
    import time

    from tests.calibration.bombs import png_bomb

    bomb = struct.pack("<q", 0) + png_bomb(16000, 16000)
    with site.client.websocket_connect(WS, headers=site.h("operator")) as ws:
        t0 = time.perf_counter()
        ws.send_bytes(bomb)
        error = json.loads(ws.receive_text())["error"]
        assert time.perf_counter() - t0 < 0.5
    assert error.startswith("frame: 256 MP is more than 16.8 MP"), error
