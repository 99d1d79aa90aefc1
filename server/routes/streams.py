"""Live streams: `WS /poses/ws` (poses as JSON), `GET /events/stream` (SSE), `GET /events`."""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import AsyncIterator
from typing import Annotated

from fastapi import APIRouter, Query, WebSocket, WebSocketDisconnect, status
from fastapi.responses import StreamingResponse
from pydantic import BaseModel

from server.auth import Viewer, authenticate
from server.bus import Subscription
from server.deps import ServicesDep
from server.poses import PoseUpdate

router = APIRouter(tags=["streams"])
SSE_HEARTBEAT_S = 15.0
RobotFilter = Annotated[list[str] | None, Query(description="only these robots")]


class EventPublic(BaseModel):
    id: int
    t: str
    kind: str
    message: str
    robot: str | None
    landmark_id: int | None
    data: dict[str, object]


async def _close_on_disconnect(ws: WebSocket, sub: Subscription[PoseUpdate]) -> None:
    with contextlib.suppress(Exception):
        while True:
            msg = await ws.receive()
            if msg["type"] == "websocket.disconnect":
                break
    sub.close()


@router.websocket("/poses/ws")
async def poses_ws(ws: WebSocket, robot: RobotFilter = None) -> None:
    """Every robot's poses (or those named by repeated `?robot=`) as they are computed.

    Each message is a JSON array of pose objects (several when the client fell behind a
    little); a client that falls far behind loses the oldest (bounded queue). Auth: the
    `Authorization: Bearer` header or `?token=`.
    """
    principal = authenticate(ws)
    if principal is None:
        await ws.close(code=status.WS_1008_POLICY_VIOLATION, reason="a valid API key is required")
        return
    await ws.accept()
    services = ws.app.state.services
    sub = services.subscribe_poses(set(robot) if robot else None)
    watcher = asyncio.create_task(_close_on_disconnect(ws, sub))
    try:
        while not sub.closed:
            batch = await sub.get_batch()
            if not batch:
                continue
            await ws.send_text("[" + ",".join(p.json for p in batch) + "]")
    except (WebSocketDisconnect, RuntimeError, OSError):
        pass
    finally:
        sub.close()
        watcher.cancel()
        with contextlib.suppress(asyncio.CancelledError, Exception):
            await watcher


@router.get("/events")
def list_events(
    services: ServicesDep, _: Viewer, limit: int = Query(100, ge=1, le=1000)
) -> list[EventPublic]:
    """The newest site events first."""
    return [EventPublic(**e.to_dict()) for e in services.events.recent(limit)]


@router.get("/events/stream", response_class=StreamingResponse)
async def event_stream(
    services: ServicesDep,
    _: Viewer,
    limit: int | None = Query(None, ge=1, le=10_000, description="end after this many events"),
) -> StreamingResponse:
    """Server-sent events: `event: <kind>` with the event as JSON in `data:` (low_battery,
    landmark_unreachable, robot_lost, map_changed, ...); a comment line every 15 s."""
    sub = services.events.bus.subscribe()

    async def stream() -> AsyncIterator[str]:
        sent = 0
        try:
            yield ": connected\n\n"
            while limit is None or sent < limit:
                try:
                    batch = await asyncio.wait_for(sub.get_batch(), SSE_HEARTBEAT_S)
                except TimeoutError:
                    yield ": heartbeat\n\n"
                    continue
                for event in batch[: None if limit is None else limit - sent]:
                    yield f"id: {event.id}\nevent: {event.kind}\ndata: {event.json()}\n\n"
                    sent += 1
        finally:
            sub.close()

    return StreamingResponse(
        stream(), media_type="text/event-stream", headers={"Cache-Control": "no-cache"}
    )
