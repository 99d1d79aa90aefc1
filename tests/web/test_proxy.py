"""The viewer behind the API key, over plain HTTP and WebSocket (no browser)."""

from __future__ import annotations

import asyncio
import contextlib

import httpx
import pytest
import websockets
from websockets.typing import Subprotocol

from tests.web.conftest import ServedSite

pytestmark = pytest.mark.slow
VISER = Subprotocol("viser-v1.1.1")


def test_page_needs_a_key_and_moves_it_to_a_cookie(live_site: ServedSite) -> None:
    with httpx.Client(base_url=live_site.base) as http:
        r = http.get("/viewer/")
        assert r.status_code == 401
        data_dir = live_site.services.settings.data_dir
        assert f"irloc keys create --role viewer --data-dir {data_dir}" in r.text
        assert http.get("/viewer/?token=not-a-key").status_code == 401
        r = http.get(f"/viewer/?token={live_site.viewer_key}")
        assert r.status_code == 303 and r.headers["location"] == "/viewer/"
        cookie = r.headers["set-cookie"]
        assert "HttpOnly" in cookie and "Path=/viewer" in cookie
        page = http.get("/viewer/")  # the cookie now carries the key
        assert page.status_code == 200 and b"<html" in page.content[:200]
        bearer = http.get("/viewer/", headers={"Authorization": f"Bearer {live_site.admin_key}"})
        assert bearer.status_code == 200


def test_websocket_relays_viser_only_with_a_key(live_site: ServedSite) -> None:
    url = live_site.base.replace("http", "ws") + "/viewer"

    async def run() -> None:
        with pytest.raises(websockets.InvalidStatus):
            async with websockets.connect(url, subprotocols=[VISER]):
                pass
        headers = {"Authorization": f"Bearer {live_site.viewer_key}"}
        async with websockets.connect(
            url,
            subprotocols=[VISER],
            additional_headers=headers,
            max_size=None,
        ) as ws:
            assert ws.subprotocol == "viser-v1.1.1"
            first = await asyncio.wait_for(ws.recv(), timeout=10)
            assert isinstance(first, bytes) and len(first) > 0  # viser's msgpack state replay

    asyncio.run(run())


def test_viser_itself_listens_on_loopback_only(live_site: ServedSite) -> None:
    from web.viewer import Viewer

    assert live_site.services.settings.viewer_enabled

    with pytest.raises(ValueError, match="no login"):
        Viewer(live_site.services, host="0.0.0.0")


def test_a_crafted_share_request_opens_no_tunnel(
    live_site: ServedSite, monkeypatch: pytest.MonkeyPatch
) -> None:
    """viser's Share button is hidden; a client that sends viser's share request anyway
    (here a plain WebSocket through the keyed proxy, an admin's key) is refused: no tunnel
    to viser's unkeyed port is opened, and the refusal is counted and logged."""
    import msgspec
    import viser._viser
    from viser import _messages

    opened: list[object] = []

    class NoTunnel:
        def __init__(self, *args: object, **kwargs: object) -> None:
            opened.append(args)
            raise AssertionError("a share tunnel was opened")

    monkeypatch.setattr(viser._viser, "ViserTunnel", NoTunnel)
    viewer = live_site.app.state.viewer
    before = viewer.share_refusals
    url = live_site.base.replace("http", "ws") + "/viewer"
    cam = _messages.ViewerCameraMessage(
        (1.0, 0.0, 0.0, 0.0), (0.0, -8.0, 6.0), 1.0, 0.01, 100.0, 800, 1280,
        (3.0, 2.4, 1.0), (0.0, 0.0, 1.0),
    )  # fmt: skip

    async def run() -> None:
        headers = {"Authorization": f"Bearer {live_site.admin_key}"}
        async with websockets.connect(
            url, subprotocols=[VISER], additional_headers=headers, max_size=None
        ) as ws:
            await ws.send(msgspec.msgpack.encode(cam.as_serializable_dict()))
            request = _messages.ShareUrlRequest()
            await ws.send(msgspec.msgpack.encode(request.as_serializable_dict()))
            deadline = asyncio.get_running_loop().time() + 10
            while viewer.share_refusals == before:
                assert asyncio.get_running_loop().time() < deadline, "request never seen"
                with contextlib.suppress(TimeoutError):
                    await asyncio.wait_for(ws.recv(), timeout=0.2)

    asyncio.run(run())
    assert viewer.share_refusals == before + 1
    assert opened == []
    assert viewer.server.request_share_url.__name__ == "no_share"


def test_the_viewer_download_link_needs_an_operator(live_site: ServedSite) -> None:
    import io
    import time
    import zipfile

    recordings = live_site.services.recordings
    name = recordings.start("r2").name
    time.sleep(0.5)
    recordings.stop("r2")
    with httpx.Client(base_url=live_site.base) as http:
        url = f"/viewer/recordings/{name}.zip"
        assert http.get(url).status_code == 401
        h = {"Authorization": f"Bearer {live_site.viewer_key}"}
        assert http.get(url, headers=h).status_code == 403
        h = {"Authorization": f"Bearer {live_site.operator_key}"}
        r = http.get(url, headers=h)
        assert (
            r.status_code == 200
            and f"{name}/map.json" in zipfile.ZipFile(io.BytesIO(r.content)).namelist()
        )
        assert http.get("/viewer/recordings/nothing.zip", headers=h).status_code == 404
    recordings.catalog.delete(name)
