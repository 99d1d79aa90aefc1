"""A live site for the viewer's end-to-end tests: the API app in-process (uvicorn on a free
port, a temporary data folder, the `demo` virtual site), started once per test module (a
site left running takes most of a core from the tests after it)."""

from __future__ import annotations

import os
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import viser

REPO = Path(__file__).resolve().parents[2]
ARTIFACTS = REPO / "test-artifacts"
DOC_IMAGES = REPO / "docs" / "img"


@dataclass
class ServedSite:
    base: str
    app: Any
    services: Any
    admin_key: str
    operator_key: str
    viewer_key: str


@contextmanager
def running_site(data: Path, *, seed: int = 5) -> Iterator[tuple[Any, int]]:
    """The API app with the `demo` virtual site, served on a free port: (app, port)."""
    import uvicorn

    from irloc.serve import make_viewer
    from live.settings import Settings
    from server.main import create_app

    settings = Settings(data_dir=data, port=0, viewer_port=0, scenario="demo", seed=seed)
    app = create_app(settings, make_viewer(settings))  # as `irloc serve` wires it
    # log_config=None: uvicorn's loggers go to the root logger, so an exception in a route
    # shows in the failing test's captured log (uvicorn's own handler would write to the
    # stderr capture of the module's first test, closed by then)
    config = uvicorn.Config(
        app, host="127.0.0.1", port=0, log_level="warning", lifespan="on", log_config=None
    )
    server = uvicorn.Server(config)
    thread = threading.Thread(target=server.run, name="uvicorn-test", daemon=True)
    thread.start()
    deadline = time.monotonic() + 60
    while not server.started:
        if time.monotonic() > deadline or not thread.is_alive():
            raise RuntimeError("the irloc app did not start")
        time.sleep(0.05)
    try:
        yield app, server.servers[0].sockets[0].getsockname()[1]
    finally:
        server.should_exit = True
        thread.join(timeout=30)


@pytest.fixture
def server() -> Iterator[viser.ViserServer]:
    """A viser server on a free loopback port, for panels driven without a browser."""
    s = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    try:
        yield s
    finally:
        s.stop()


def without_image_based_lighting(app: Any) -> None:
    """Turn off viser's environment map (its default image-based lighting) in the served
    site's scene, unless the README pictures are being made (`IRLOC_UPDATE_DOC_IMAGES=1`:
    they show the viewer as staff see it).

    Headless Chromium draws WebGL in software: each page that loads the environment map
    prefilters it (PMREM) on the page's main thread, which then answers nothing for 10 s or
    more on a busy 2-core machine, and every browser test opens a page or more. What the
    tests check (scene nodes, panels, the colours of trails, zones and the floor plan's
    walls) comes from the same nodes and materials without it: the default lights still
    light the scene, its colours only come out less washed out.
    """
    if os.environ.get("IRLOC_UPDATE_DOC_IMAGES") != "1":
        app.state.viewer.server.scene.configure_environment_map(None)


@pytest.fixture(scope="module")
def live_site(tmp_path_factory: pytest.TempPathFactory) -> Iterator[ServedSite]:
    with running_site(tmp_path_factory.mktemp("irloc-data")) as (app, port):
        without_image_based_lighting(app)
        services = app.state.services
        keys = {
            role: services.keys.create(role, f"test-{role}")[0]
            for role in ("admin", "operator", "viewer")
        }
        yield ServedSite(
            f"http://127.0.0.1:{port}",
            app,
            services,
            keys["admin"],
            keys["operator"],
            keys["viewer"],
        )


def nearest_landmarks(services: Any, robot: str, n: int) -> list[int]:
    """The `n` reachable landmarks nearest the robot's true position now (the truth only
    picks which landmarks a test works on)."""
    x, y, _ = services.virtual_site.true_pose(robot)
    lms = [lm for lm in services.virtual_site.world.landmarks.values() if lm.reachable]
    lms.sort(key=lambda lm: np.hypot(lm.p_true[0] - x, lm.p_true[1] - y))
    return [int(lm.id) for lm in lms[:n]]


def patrol_route(services: Any, robot: str) -> np.ndarray:
    """Points (N, 2) along a simulated robot's patrol loop, metres."""
    spec = next(r for r in services.virtual_site.scenario.robots if r.name == robot)
    corners = [(float(spec.start[0]), float(spec.start[1]))]
    corners += [(float(st.x), float(st.y)) for st in spec.route.steps if hasattr(st, "x")]
    return np.vstack(
        [np.linspace(a, b, 20) for a, b in zip(corners, corners[1:] + corners[:1], strict=True)]
    )


def landmark_always_in_view(services: Any, robot: str) -> int:
    """The reachable landmark nearest to the robot's whole patrol route (the largest
    horizontal distance from the route is the smallest): in its camera's view wherever it
    is when a slow step (a browser click) finally measures it."""
    route = patrol_route(services, robot)
    lms = [lm for lm in services.virtual_site.world.landmarks.values() if lm.reachable]

    def worst(lm: Any) -> float:
        return float(np.max(np.hypot(route[:, 0] - lm.p_true[0], route[:, 1] - lm.p_true[1])))

    return int(min(lms, key=worst).id)


def wait_localized(
    site: Any, robot: str, services: Any, *, tol_m: float = 0.02, timeout_s: float = 60.0
) -> None:
    """Wait until the robot's localizer holds a landmark fix that agrees with the simulator's
    truth for the same frame (the truth checks the localizer; it never feeds the wizard).

    A robot locked onto a wrong fix (in a regular grid, a fix shifted by whole cells is
    self-consistent: a localizer issue, not the viewer's) is relocalized, as an operator
    would with the viewer's Relocalize button, at most every 15 s.
    """
    deadline = time.monotonic() + timeout_s
    last_relocalize = wrong_since = None
    err = None
    while time.monotonic() < deadline:
        rb = next(r for r in site.robots() if r.name == robot)
        truth = None if rb.pose is None else services.virtual_site.true_pose_at(robot, rb.pose.t_ns)
        if rb.mode == "landmark" and rb.pose is not None and truth is not None:
            err = float(np.hypot(rb.pose.x - truth[0], rb.pose.y - truth[1]))
            now = time.monotonic()
            if err <= tol_m:
                return
            wrong_since = wrong_since or now
            if (
                err > 0.5
                and now - wrong_since > 2.0
                and (last_relocalize is None or now - last_relocalize > 15.0)
            ):
                site.relocalize(robot, actor="test")
                last_relocalize, wrong_since = now, None
        else:
            wrong_since = None
        time.sleep(0.1)
    raise AssertionError(
        f"{robot} did not hold a correct landmark fix in {timeout_s} s (last error {err} m)"
    )
