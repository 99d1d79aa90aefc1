"""Live streams: `WS /poses/ws` (poses as JSON), `GET /events/stream` (SSE), `GET /events`."""

from __future__ import annotations

import asyncio
import contextlib
import json
from collections.abc import AsyncIterator
from typing import Annotated

from fastapi import (
    APIRouter,
    Header,
    Query,
    Request,
    WebSocket,
    WebSocketDisconnect,
    status,
)
from fastapi.responses import StreamingResponse
from pydantic import BaseModel, Field

from live.events import EventKind
from server.auth import Viewer, websocket_principal
from server.deps import ServicesDep
from server.fanout import FanoutClient, PoseFanout
from server.stream_guard import KEY_REVOKED, stream_end

router = APIRouter(tags=["streams"])
SSE_HEARTBEAT_S = 15.0
RobotFilter = Annotated[list[str] | None, Query(description="only these robots")]


class EventPublic(BaseModel):
    """One site event."""

    id: int = Field(description="increasing: page back with ?before_id=, resume SSE with it")
    t: str = Field(description="when, ISO 8601 in UTC (wall clock)")
    kind: EventKind
    message: str = Field(description="for people")
    robot: str | None
    landmark_id: int | None
    data: dict[str, object]


KindFilter = Annotated[
    list[EventKind] | None, Query(description="only these kinds (repeat: ?kind=a&kind=b)")
]


async def _close_on_disconnect(ws: WebSocket, client: FanoutClient) -> None:
    with contextlib.suppress(Exception):
        while True:
            msg = await ws.receive()
            if msg["type"] == "websocket.disconnect":
                break
    client.close()


@router.websocket("/poses/ws")
async def poses_ws(ws: WebSocket, robot: RobotFilter = None) -> None:
    """Every robot's poses (or those named by repeated `?robot=`) as they are computed.

    Each message is a JSON array of pose objects (the poses computed within a few
    milliseconds of each other); a client that falls behind loses the oldest messages
    (bounded queue, `irloc_ws_dropped_poses_total`). Auth: the `Authorization: Bearer`
    header or `?token=`. Closed with code 1008 and a reason when the key is refused or
    revoked, 1001 or 1012 when the server shuts down.
    """
    principal = await websocket_principal(ws, "viewer")
    if principal is None:
        return
    await ws.accept()
    services = ws.app.state.services
    known = set(services.robots.names()) | {r.name for r in services.robot_store.list()}
    unknown = sorted(set(robot or ()) - known) if known else []  # no robots: cannot tell
    if unknown:  # a filter that matches nothing would stay silent forever
        await ws.close(
            code=status.WS_1008_POLICY_VIOLATION,
            reason=f"unknown robot(s) {', '.join(unknown)}; robots: {', '.join(sorted(known))}"[
                :120
            ],
        )
        return
    fanout: PoseFanout = ws.app.state.pose_fanout
    client = fanout.add_client(robot, ws.app.state.services.settings.ws_queue)
    watcher = asyncio.create_task(_close_on_disconnect(ws, client))
    guard = asyncio.create_task(stream_end(ws, principal))
    guard.add_done_callback(lambda _: client.close())
    try:
        while (message := await client.get()) is not None:
            await ws.send_text(message)
    except (WebSocketDisconnect, RuntimeError, OSError):
        pass
    finally:
        fanout.remove_client(client)
        for task in (watcher, guard):
            task.cancel()
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await task
        if guard.done() and not guard.cancelled() and guard.exception() is None:
            code = status.WS_1008_POLICY_VIOLATION
            if guard.result() != KEY_REVOKED:
                code = status.WS_1001_GOING_AWAY
            with contextlib.suppress(Exception):
                await ws.close(code=code, reason=guard.result())


@router.get("/events")
def list_events(
    services: ServicesDep,
    _: Viewer,
    limit: int = Query(100, ge=1, le=1000),
    kind: KindFilter = None,
    robot: str | None = Query(None, max_length=64, description="only this robot's events"),
    before_id: int | None = Query(
        None,
        ge=1,
        description="only events older than this id: the next page is "
        "?before_id=<the last id of this page>",
    ),
) -> list[EventPublic]:
    """The newest site events first, `limit` a page, filtered by kind and robot."""
    events = services.events.recent(limit, kinds=kind, before_id=before_id, robot=robot)
    return [EventPublic(**e.to_dict()) for e in events]


@router.get("/events/stream", response_class=StreamingResponse)
async def event_stream(
    request: Request,
    services: ServicesDep,
    who: Viewer,
    limit: int | None = Query(None, ge=1, le=10_000, description="end after this many events"),
    last_event_id: int | None = Header(
        None,
        ge=0,
        description="resume: first the stored events after this id (a browser's "
        "EventSource sends it when it reconnects), then the live ones",
    ),
) -> StreamingResponse:
    """Server-sent events: `id: <id>`, `event: <kind>` with the event as JSON in `data:`
    (low_battery, landmark_unreachable, robot_lost, map_changed, ...); a comment line every
    15 s. With `Last-Event-ID` the events stored since that one come first (up to 1000). The
    stream ends with `event: key_revoked` when the key is revoked and `event: shutdown` when
    the server stops."""
    sub = services.events.bus.subscribe()  # before the replay: nothing falls in between
    missed = [] if last_event_id is None else services.events.recent(1000, after_id=last_event_id)

    async def stream() -> AsyncIterator[str]:
        sent = 0
        newest = last_event_id or 0
        guard = asyncio.create_task(stream_end(request, who))
        try:
            yield ": connected\n\n"
            for event in missed[: None if limit is None else limit]:
                yield f"id: {event.id}\nevent: {event.kind}\ndata: {event.json()}\n\n"
                sent += 1
                newest = max(newest, event.id)
            while limit is None or sent < limit:
                getter = asyncio.ensure_future(sub.get_batch())
                done, _ = await asyncio.wait(
                    {getter, guard}, timeout=SSE_HEARTBEAT_S, return_when=asyncio.FIRST_COMPLETED
                )
                if guard in done:
                    getter.cancel()
                    kind = "key_revoked" if guard.result() == KEY_REVOKED else "shutdown"
                    yield f"event: {kind}\ndata: {json.dumps({'message': guard.result()})}\n\n"
                    return
                if getter not in done:
                    getter.cancel()
                    yield ": heartbeat\n\n"
                    continue
                fresh = [e for e in getter.result() if e.id > newest]  # not replayed already
                for event in fresh[: None if limit is None else limit - sent]:
                    yield f"id: {event.id}\nevent: {event.kind}\ndata: {event.json()}\n\n"
                    sent += 1
        finally:
            guard.cancel()
            sub.close()

    return StreamingResponse(
        stream(), media_type="text/event-stream", headers={"Cache-Control": "no-cache"}
    )
