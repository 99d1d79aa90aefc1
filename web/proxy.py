"""`viewer_router`: the viewer on the API's own port, behind the API key.

- `GET /viewer/` serves viser's client page (the installed viser package's `client/build`).
  A key in `?token=` (or `?key=`) is checked, stored in an HttpOnly cookie scoped to
  `/viewer`, and the browser is redirected to the bare URL so the key leaves the address bar.
  `Authorization: Bearer <key>` works too. Without a valid key: 401.
- `WS /viewer` (where viser's client connects from that page; `/viewer/` too): the key
  (cookie, header or query) is checked, then the connection is relayed to viser on
  127.0.0.1 with the client's `viser-v<version>` subprotocol passed through and a one-time
  ticket that tells the viewer the role (viewers see; operators relocalize; admins commission).
"""

from __future__ import annotations

import asyncio
import contextlib
import html
import logging
from collections.abc import Callable
from pathlib import Path
from typing import Protocol
from urllib.parse import urlencode

import viser
import websockets
from fastapi import APIRouter, BackgroundTasks, Request, WebSocket, WebSocketDisconnect
from fastapi.responses import (
    FileResponse,
    HTMLResponse,
    PlainTextResponse,
    RedirectResponse,
    Response,
)
from starlette.requests import HTTPConnection
from websockets.asyncio.client import ClientConnection

from server.edge import same_origin
from server.seams import Authenticate
from store.errors import ConflictError, NotFoundError
from web.roles import TICKET_PARAM, Session

log = logging.getLogger(__name__)
COOKIE = "irloc_viewer_key"
KEY_PARAMS = ("token", "key")


def client_build_dir() -> Path:
    """The installed viser package's client build (index.html)."""
    return Path(viser.__file__).parent / "client" / "build"


def key_of(conn: HTTPConnection) -> str | None:
    """The API key a browser sent: `Authorization: Bearer`, then the cookie, then the query."""
    scheme, _, value = conn.headers.get("authorization", "").partition(" ")
    if scheme.lower() == "bearer" and value.strip():
        return value.strip()
    cookie = conn.cookies.get(COOKIE)
    if cookie:
        return cookie
    for name in KEY_PARAMS:
        v = conn.query_params.get(name)
        if v:
            return v
    return None


def _with_bearer(conn: HTTPConnection, key: str) -> HTTPConnection:
    """The same connection seen with `Authorization: Bearer <key>` only (for `authenticate`)."""
    scope = dict(conn.scope)
    headers = [(k, v) for k, v in scope.get("headers", []) if k.lower() != b"authorization"]
    scope["headers"] = [*headers, (b"authorization", f"Bearer {key}".encode("latin-1"))]
    scope["query_string"] = b""
    return HTTPConnection(scope)


class TicketIssuer(Protocol):
    """The running viewer as the proxy needs it (`web.viewer.Viewer`)."""

    @property
    def port(self) -> int: ...

    def issue_ticket(self, session: Session) -> str: ...

    def recording_zip(self, name: str) -> Path: ...


def session_of(conn: HTTPConnection, authenticate: Authenticate) -> Session | None:
    """The viewer session of a request, or None without a valid key."""
    key = key_of(conn)
    if key is None:
        return None
    try:
        principal = authenticate(_with_bearer(conn, key))
    except (UnicodeEncodeError, ValueError):
        return None
    if principal is None:
        return None
    # "web:key:3": the web app's user (not "viewer:", which read like the viewer role)
    return Session(str(principal.role), f"web:{principal.actor}")


NO_KEY_PAGE = """<!doctype html><meta charset="utf-8"><title>irloc viewer</title>
<style>body {{ font-family: system-ui, sans-serif; max-width: 44rem; margin: 2rem auto; }}
code {{ background: #f2f2f2; padding: 0 0.25rem; }}</style>
<h1>irloc viewer</h1><p>This page needs an API key: open
<code>/viewer/?token=KEY</code>, or paste the key here:</p>
<form action="/viewer/" method="get"><input name="token" type="password" placeholder="API key"
autocomplete="off"> <button type="submit">Open the viewer</button></form>
<p>Create a key on the server's machine with
<code>irloc keys create --role viewer --data-dir {data_dir}</code>
(<code>--role operator</code> or <code>admin</code> to act, not only watch).
<a href="/">Home</a></p>"""


def no_key_page(conn: HTTPConnection) -> str:
    """The 401 page, naming this server's data folder in the `irloc keys create` hint."""
    services = getattr(conn.app.state, "services", None)
    settings = getattr(services, "settings", None)
    data_dir = str(getattr(settings, "data_dir", "DIR"))
    return NO_KEY_PAGE.format(data_dir=html.escape(data_dir))


def viewer_router(
    get_viewer: Callable[[], TicketIssuer | None], authenticate: Authenticate
) -> APIRouter:
    """Routes serving the viewer under `/viewer/`.

    Args:
        get_viewer: returns the running `web.viewer.Viewer` (None when disabled).
        authenticate: `server.auth.authenticate`: a connection -> principal with `role` and
            `actor`, or None for a missing or invalid key.
    """
    router = APIRouter(tags=["viewer"], include_in_schema=False)
    index = client_build_dir() / "index.html"

    @router.get("/viewer")
    async def viewer_no_slash(request: Request) -> Response:
        q = request.url.query
        return RedirectResponse("/viewer/" + (f"?{q}" if q else ""), status_code=307)

    @router.get("/viewer/")
    async def viewer_page(request: Request) -> Response:
        if get_viewer() is None:
            return HTMLResponse("<h1>the viewer is not running</h1>", status_code=503)
        session = session_of(request, authenticate)
        if session is None:
            return HTMLResponse(no_key_page(request), status_code=401)
        query_key = next(
            (request.query_params[n] for n in KEY_PARAMS if n in request.query_params), None
        )
        if query_key is not None:
            rest = [(k, v) for k, v in request.query_params.multi_items() if k not in KEY_PARAMS]
            target = "/viewer/" + (f"?{urlencode(rest)}" if rest else "")
            resp: Response = RedirectResponse(target, status_code=303)
            resp.set_cookie(
                COOKIE,
                query_key,
                httponly=True,
                samesite="strict",
                path="/viewer",
                secure=request.url.scheme == "https",
            )
            return resp
        return HTMLResponse(index.read_bytes(), headers={"Cache-Control": "no-store"})

    @router.get("/viewer/recordings/{name}.zip")
    def recording_download(name: str, request: Request, background: BackgroundTasks) -> Response:
        """A recording for the Recordings panel's link (the key is the `/viewer` cookie):
        operators and admins, as `GET /api/v1/recordings/{name}/download`."""
        viewer = get_viewer()
        session = session_of(request, authenticate)
        if viewer is None or session is None:
            return HTMLResponse(no_key_page(request), status_code=401)
        if not session.can_operate:
            return PlainTextResponse("downloading a recording needs an operator key", 403)
        try:
            tmp = viewer.recording_zip(name)
        except NotFoundError as exc:
            return PlainTextResponse(str(exc), 404)
        except ConflictError as exc:
            return PlainTextResponse(str(exc), 409)
        background.add_task(tmp.unlink, missing_ok=True)
        return FileResponse(tmp, media_type="application/zip", filename=f"{name}.zip")

    @router.websocket("/viewer")
    @router.websocket("/viewer/")
    async def viewer_socket(ws: WebSocket) -> None:
        viewer = get_viewer()
        if not same_origin(ws):
            await ws.close(code=1008, reason="the viewer is only served to its own pages")
            return
        session = session_of(ws, authenticate)
        if viewer is None or session is None:
            await ws.close(code=1008, reason="a valid API key is required")
            return
        offered = [p.strip() for p in ws.headers.get("sec-websocket-protocol", "").split(",")]
        proto = next((p for p in offered if p.startswith("viser-v")), None)
        ticket = viewer.issue_ticket(session)
        url = f"ws://127.0.0.1:{viewer.port}/?{TICKET_PARAM}={ticket}"
        try:
            upstream = await websockets.connect(
                url,
                subprotocols=[proto] if proto else None,  # type: ignore[list-item]
                max_size=None,
                open_timeout=10,
                ping_interval=None,
            )
        except (OSError, websockets.WebSocketException) as exc:
            log.warning("viewer proxy: cannot reach viser on port %s: %s", viewer.port, exc)
            await ws.close(code=1011, reason="viewer unavailable")
            return
        await ws.accept(subprotocol=upstream.subprotocol)
        await relay(ws, upstream)

    return router


async def relay(ws: WebSocket, upstream: ClientConnection) -> None:
    """Copy messages both ways until either side closes; then close the other."""

    async def down() -> None:
        async for msg in upstream:
            if isinstance(msg, bytes):
                await ws.send_bytes(msg)
            else:
                await ws.send_text(msg)

    async def up() -> None:
        while True:
            msg = await ws.receive()
            if msg["type"] == "websocket.disconnect":
                return
            data = msg.get("bytes")
            await upstream.send(data if data is not None else msg.get("text", ""))

    tasks = [asyncio.create_task(down()), asyncio.create_task(up())]
    try:
        await asyncio.wait(tasks, return_when=asyncio.FIRST_COMPLETED)
    finally:
        for t in tasks:
            t.cancel()
        await asyncio.gather(*tasks, return_exceptions=True)
        await upstream.close()
        with contextlib.suppress(RuntimeError, WebSocketDisconnect):
            await ws.close()
