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

import httpx
import uvicorn

from live.services import SiteServices
from tests.server.conftest import Api, make_test_app, role_keys


@contextmanager
def served(app: Any) -> Iterator[str]:
    """Serve `app` (its lifespan runs) on 127.0.0.1 and yield its base URL."""
    config = uvicorn.Config(
        app, host="127.0.0.1", port=0, log_config=None, access_log=False, lifespan="on"
    )  # (log_config=None: leaves the test process's logging alone)
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
class LiveApi(Api):
    """A served app: the `Api` of a test (its `client` talks to the real server) and the URL."""

    url: str = ""


@contextmanager
def live_api(data_dir: Path, **settings: object) -> Iterator[LiveApi]:
    """The app (the live virtual site unless `site_enabled=False`) served on a free port."""
    app = make_test_app(data_dir, **settings)
    with served(app) as url, httpx.Client(base_url=url) as client:
        services: SiteServices = app.state.services
        yield LiveApi(client, services, role_keys(services), url)  # type: ignore[arg-type]
