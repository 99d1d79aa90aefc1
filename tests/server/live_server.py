"""The app served by a real uvicorn on a free loopback port, in a thread of the test process
(for clients that need a URL: schemathesis's extra requests, a generated client)."""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import uvicorn

from server.main import create_app
from server.services import SiteServices
from server.settings import Settings


@contextmanager
def served(app: Any) -> Iterator[str]:
    """Serve `app` (its lifespan runs) on 127.0.0.1 and yield its base URL."""
    config = uvicorn.Config(app, host="127.0.0.1", port=0, log_level="warning", lifespan="on")
    server = uvicorn.Server(config)
    thread = threading.Thread(target=server.run, name="live-server", daemon=True)
    thread.start()
    deadline = time.monotonic() + 60
    while not server.started:
        if not thread.is_alive() or time.monotonic() > deadline:
            raise RuntimeError("the live test server did not start")
        time.sleep(0.02)
    port = server.servers[0].sockets[0].getsockname()[1]
    try:
        yield f"http://127.0.0.1:{port}"
    finally:
        server.should_exit = True
        thread.join(timeout=30)


@dataclass
class LiveApi:
    """A served app: its URL, services and a key per role."""

    url: str
    services: SiteServices
    keys: dict[str, str]

    def h(self, role: str) -> dict[str, str]:
        return {"Authorization": f"Bearer {self.keys[role]}"}


@contextmanager
def live_api(data_dir: Path, **settings: object) -> Iterator[LiveApi]:
    """The app (the live virtual site unless `site_enabled=False`) served on a free port."""
    conf: dict[str, object] = {
        "data_dir": data_dir,
        "viewer_enabled": False,
        "battery_interval_s": None,
    }
    app = create_app(Settings(**{**conf, **settings}))  # type: ignore[arg-type]
    with served(app) as url:
        services: SiteServices = app.state.services
        admin = services.initial_admin_key
        if admin is None:
            raise RuntimeError(f"{data_dir}: expected a fresh data folder")
        keys = {"admin": admin}
        for role in ("operator", "viewer"):
            keys[role], _ = services.keys.create(role, name=f"test {role}")
        yield LiveApi(url, services, keys)
