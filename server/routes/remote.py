"""`WS /robots/{name}/ws`: a remote robot pushes frames (or detected spots) and wheel speeds.

Text messages are JSON:
- `{"type": "odometry", "v_left": 0.2, "v_right": 0.21, "t_ns": 123}`
- `{"type": "spots", "pixels": [[c, r], ...], "intensities": [...], "areas": [...], "t_ns": 123}`
Binary messages are frames: 8 bytes little-endian signed `t_ns` then a PNG or JPEG image
(8-bit gray or colour, or 16-bit PNG), or a raw gray frame: `GRY8` (8-bit) or `GR16` (16-bit
LE), uint32 LE width, uint32 LE height, then the pixels row-major. Frames are decoded off the
event loop, at most 4096 x 4096 px (an encoded image's size is read from its header first).
`t_ns` is on the server's site clock; omit it (or send 0 / null) to stamp on receipt. The
server answers each frame or spots message with the resulting pose as JSON (as on
`/poses/ws`), and a malformed message with `{"error": "<what is wrong>"}` (the connection
stays open). The robot must have source `remote`; when the connection closes, its localizer
keeps its state and waits (no more poses until the robot reconnects).
"""

from __future__ import annotations

import asyncio
import json
import struct
from collections.abc import Callable
from typing import Any

import numpy as np
from fastapi import APIRouter, WebSocket, WebSocketDisconnect

from calibration.uploads import decode_image
from live.robots import RobotRunner
from live.services import SiteServices
from localizer.events import FrameObserved, OdometryMeasured, SpotsObserved
from sensors.camera import to_gray
from sensors.remote import RemoteSource
from sensors.serial_wheels import MAX_WHEEL_SPEED
from sensors.sources import SensorEvent
from server.auth import refuse_websocket, websocket_principal
from store.errors import NotFoundError

router = APIRouter(tags=["robots"])
MAX_SPOTS = 1000


MAX_T_NS = 2**62


Clock = Callable[[], int]
"""The site clock, nanoseconds (`SiteServices.clock_ns`)."""


def _t(clock_ns: Clock, value: object) -> int:
    """A message's `t_ns`: absent, null or 0 stamps on receipt (site clock)."""
    if value is None or value == 0:
        return int(clock_ns())
    if not isinstance(value, int) or isinstance(value, bool) or not 0 < value < MAX_T_NS:
        raise ValueError(f"t_ns: expected a positive integer (site clock, ns), got {value!r}")
    return value


def _array(msg: dict[str, Any], key: str, shape: tuple[int, ...]) -> np.ndarray:
    try:
        arr = np.asarray(msg.get(key, []), dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"spots: {key} must be numbers") from None
    if arr.size == 0:
        arr = arr.reshape((0, *shape[1:]))
    if arr.ndim != len(shape) or arr.shape[1:] != shape[1:]:
        want = "(N, 2)" if len(shape) == 2 else "(N,)"
        raise ValueError(f"spots: {key} must have shape {want}, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"spots: {key} must be finite")
    return arr


def event_from_text(clock_ns: Clock, text: str) -> OdometryMeasured | SpotsObserved:
    """Parse one JSON message; ValueError names the bad field."""
    try:
        msg = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ValueError(f"message is not JSON: {exc}") from None
    if not isinstance(msg, dict):
        raise ValueError("message must be a JSON object")
    kind = msg.get("type")
    t_ns = _t(clock_ns, msg.get("t_ns"))
    if kind == "odometry":
        speeds: list[float] = []
        for key in ("v_left", "v_right"):
            v = msg.get(key)
            if (
                not isinstance(v, int | float)
                or isinstance(v, bool)
                or not abs(v) <= MAX_WHEEL_SPEED
            ):
                raise ValueError(
                    f"odometry: {key} must be a number in [-{MAX_WHEEL_SPEED}, "
                    f"{MAX_WHEEL_SPEED}] m/s, got {v!r}"
                )
            speeds.append(float(v))
        return OdometryMeasured(t_ns, speeds[0], speeds[1])
    if kind == "spots":
        px = _array(msg, "pixels", (0, 2))
        inten = _array(msg, "intensities", (0,))
        areas = _array(msg, "areas", (0,))
        n = len(px)
        if len(inten) != n or len(areas) != n:
            raise ValueError(
                f"spots: {n} pixels but {len(inten)} intensities and {len(areas)} areas"
            )
        if n > MAX_SPOTS:
            raise ValueError(f"spots: {n} spots, at most {MAX_SPOTS}")
        return SpotsObserved(t_ns, px, inten, areas)
    raise ValueError(f"type: expected 'odometry' or 'spots', got {kind!r}")


RAW_FORMATS: dict[bytes, np.dtype[Any]] = {b"GRY8": np.dtype(np.uint8), b"GR16": np.dtype("<u2")}
"""Raw frame magic -> pixel type (row-major gray, little-endian)."""
MAX_RAW_PIXELS = 4096 * 4096


def raw_frame(data: bytes) -> np.ndarray:
    """A raw frame: 4-byte magic (`GRY8` | `GR16`), uint32 LE width, uint32 LE height, then
    width x height pixels, row-major. ValueError names what does not fit."""
    if len(data) < 12:
        raise ValueError("frame: raw header is 4-byte magic, uint32 width, uint32 height")
    dtype = RAW_FORMATS[data[:4]]
    width, height = struct.unpack("<II", data[4:12])
    if not 0 < width * height <= MAX_RAW_PIXELS:
        raise ValueError(f"frame: raw size {width} x {height} px is empty or too large")
    expected = width * height * dtype.itemsize
    if len(data) - 12 != expected:
        raise ValueError(
            f"frame: raw {data[:4].decode()} {width} x {height} needs {expected} pixel bytes, "
            f"got {len(data) - 12}"
        )
    pixels: np.ndarray = np.frombuffer(data, dtype=dtype, offset=12)
    return pixels.reshape(height, width)


def frame_from_bytes(clock_ns: Clock, data: bytes) -> FrameObserved:
    """A binary message: 8-byte LE `t_ns`, then a PNG/JPEG image or a raw frame."""
    if len(data) < 9:
        raise ValueError("frame: 8-byte t_ns then an encoded image expected")
    (t_raw,) = struct.unpack("<q", data[:8])
    payload = data[8:]
    image: np.ndarray | None
    if payload[:4] in RAW_FORMATS:
        image = raw_frame(payload)
    else:
        image = decode_image("frame", payload, max_pixels=MAX_RAW_PIXELS)
        if image is None:
            raise ValueError(
                f"frame: the {len(payload)} bytes after t_ns are neither a PNG/JPEG image nor "
                "a raw frame (GRY8/GR16 header)"
            )
    return FrameObserved(_t(clock_ns, t_raw), to_gray(image))


@router.websocket("/robots/{name}/ws")
async def remote_robot(ws: WebSocket, name: str) -> None:
    """A remote robot's sensor stream (operator key)."""
    if await websocket_principal(ws, "operator") is None:
        return
    services: SiteServices = ws.app.state.services
    try:
        runner = services.robots.get(name)
    except NotFoundError as exc:
        await refuse_websocket(ws, str(exc))
        return
    source = None if services.runner is None else services.runner.remote(name)
    if runner.source != "remote" or source is None:
        await refuse_websocket(ws, f"robot {name!r} has source {runner.source!r}, not 'remote'")
        return
    await ws.accept()
    services.events.emit("robot_connected", f"remote robot {name} connected", robot=name)
    try:
        await _serve(ws, services.clock_ns, runner, source)
    except WebSocketDisconnect:
        pass
    finally:
        services.events.emit(
            "robot_disconnected",
            f"remote robot {name} disconnected; its pose is no longer updated",
            robot=name,
        )


async def _serve(ws: WebSocket, clock_ns: Clock, runner: RobotRunner, source: RemoteSource) -> None:
    while True:
        msg = await ws.receive()
        if msg["type"] == "websocket.disconnect":
            return
        try:
            if msg.get("bytes") is not None:  # decoded off the event loop
                data = msg["bytes"]
                event: SensorEvent = await asyncio.to_thread(frame_from_bytes, clock_ns, data)
            else:
                event = event_from_text(clock_ns, msg.get("text") or "")
        except ValueError as exc:
            await ws.send_text(json.dumps({"error": str(exc)}))
            continue
        await source.push(event)
        if not isinstance(event, OdometryMeasured):
            latest = runner.latest
            await ws.send_text(
                latest.json
                if latest is not None and latest.t_ns == event.t_ns
                else json.dumps({"robot": runner.name, "t_ns": event.t_ns, "mode": runner.mode})
            )
