"""`WS /robots/{name}/ws`: a remote robot pushes frames (or detected spots) and wheel speeds.

Text messages are JSON:
- `{"type": "odometry", "v_left": 0.2, "v_right": 0.21, "t_ns": 123}`
- `{"type": "spots", "pixels": [[c, r], ...], "intensities": [...], "areas": [...], "t_ns": 123}`
Binary messages are frames: 8 bytes little-endian signed `t_ns` then a PNG or JPEG image.
`t_ns` is on the server's site clock; omit it (or send 0) to stamp on receipt. The server
answers each frame or spots message with the resulting pose as JSON (as on `/poses/ws`).
"""

from __future__ import annotations

import asyncio
import json
import struct
from typing import Any

import cv2
import numpy as np
from fastapi import APIRouter, WebSocket, WebSocketDisconnect, status

from localizer.events import FrameObserved, OdometryMeasured, SpotsObserved
from server.auth import authenticate
from server.errors import NotFoundError

router = APIRouter(tags=["robots"])
MAX_SPOTS = 1000


def _t(services: Any, value: Any) -> int:
    if isinstance(value, int) and not isinstance(value, bool) and value > 0:
        return value
    return int(services.clock_ns())


def event_from_text(services: Any, text: str) -> OdometryMeasured | SpotsObserved:
    """Parse one JSON message; ValueError names the bad field."""
    try:
        msg = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ValueError(f"message is not JSON: {exc}") from None
    if not isinstance(msg, dict):
        raise ValueError("message must be a JSON object")
    kind = msg.get("type")
    t_ns = _t(services, msg.get("t_ns"))
    if kind == "odometry":
        v = [msg.get("v_left"), msg.get("v_right")]
        if not all(isinstance(x, int | float) and np.isfinite(x) for x in v):
            raise ValueError("odometry: v_left and v_right must be finite numbers (m/s)")
        return OdometryMeasured(t_ns, float(v[0]), float(v[1]))  # type: ignore[arg-type]
    if kind == "spots":
        try:
            px = np.asarray(msg.get("pixels", []), dtype=np.float64).reshape(-1, 2)
            inten = np.asarray(msg.get("intensities", []), dtype=np.float64).reshape(-1)
            areas = np.asarray(msg.get("areas", []), dtype=np.float64).reshape(-1)
        except (TypeError, ValueError):
            raise ValueError("spots: pixels (N,2), intensities (N,), areas (N,)") from None
        n = len(px)
        if n > MAX_SPOTS or len(inten) != n or len(areas) != n or not np.all(np.isfinite(px)):
            raise ValueError("spots: pixels (N,2), intensities (N,), areas (N,), N <= 1000")
        return SpotsObserved(t_ns, px, inten, areas)
    raise ValueError(f"type: expected 'odometry' or 'spots', got {kind!r}")


def frame_from_bytes(services: Any, data: bytes) -> FrameObserved:
    if len(data) < 9:
        raise ValueError("frame: 8-byte t_ns then an encoded image expected")
    (t_raw,) = struct.unpack("<q", data[:8])
    image = cv2.imdecode(np.frombuffer(data[8:], dtype=np.uint8), cv2.IMREAD_GRAYSCALE)
    if image is None:
        raise ValueError("frame: the image is not a readable PNG/JPEG")
    return FrameObserved(_t(services, t_raw), np.asarray(image, dtype=np.uint8))


@router.websocket("/robots/{name}/ws")
async def remote_robot(ws: WebSocket, name: str) -> None:
    """A remote robot's sensor stream (operator key)."""
    principal = authenticate(ws)
    if principal is None or not principal.allows("operator"):
        await ws.close(code=status.WS_1008_POLICY_VIOLATION, reason="an operator key is required")
        return
    services = ws.app.state.services
    try:
        runner = services.robots.get(name)
    except NotFoundError as exc:
        await ws.close(code=status.WS_1008_POLICY_VIOLATION, reason=str(exc))
        return
    await ws.accept()
    try:
        while True:
            msg = await ws.receive()
            if msg["type"] == "websocket.disconnect":
                return
            try:
                if msg.get("bytes") is not None:
                    event: Any = frame_from_bytes(services, msg["bytes"])
                else:
                    event = event_from_text(services, msg.get("text") or "")
            except ValueError as exc:
                await ws.send_text(json.dumps({"error": str(exc)}))
                continue
            await asyncio.to_thread(runner.handle, event)
            if not isinstance(event, OdometryMeasured):
                latest = runner.latest
                await ws.send_text(
                    latest.json
                    if latest is not None
                    else json.dumps({"robot": name, "mode": runner.mode})
                )
    except WebSocketDisconnect:
        return
