from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterator
from typing import Any

import numpy as np
import pytest

from server.loopback import is_loopback
from tests.web.memsite import MemSite, grid_site
from web.viewer import Viewer, ViewerConfig


@pytest.fixture
def site_viewer() -> Iterator[tuple[MemSite, Viewer]]:
    site = grid_site()
    viewer = Viewer(site, config=ViewerConfig(rate_hz=50.0, landmark_rate_hz=20.0))
    viewer.start()
    try:
        yield site, viewer
    finally:
        viewer.stop()


def wait_for(cond: Callable[[], bool], timeout_s: float = 5.0) -> None:
    deadline = time.monotonic() + timeout_s
    while not cond():
        if time.monotonic() > deadline:
            raise AssertionError("condition not met in time")
        time.sleep(0.02)


def node(viewer: Viewer, name: str) -> Any:
    assert viewer.server is not None
    h = viewer.server.scene.get_handle_by_name(name)
    assert h is not None, name
    return h


def test_refuses_a_public_viser_port() -> None:
    assert is_loopback("127.0.0.1") and is_loopback("::1") and is_loopback("localhost")
    assert not is_loopback("0.0.0.0")
    with pytest.raises(ValueError, match="no login"):
        Viewer(grid_site(), host="0.0.0.0")


def test_scene_holds_every_landmark_and_robot(site_viewer: tuple[MemSite, Viewer]) -> None:
    site, viewer = site_viewer
    assert viewer.port > 0
    wait_for(lambda: viewer.ticks > 3)
    scene = viewer.scene
    assert scene is not None
    assert scene.landmark_ids() == sorted(site.truth)
    h = node(viewer, "/landmarks/17")
    np.testing.assert_allclose(h.position, site.truth[17], atol=1e-6)
    at = node(viewer, "/robots/r1/position")
    np.testing.assert_allclose(at.position, [1.5, 1.0, 0.0], atol=1e-6)
    body = node(viewer, "/robots/r1/position/body")
    np.testing.assert_allclose(body.position, [0.0, 0.0, 0.125], atol=1e-6)
    np.testing.assert_allclose(body.wxyz, [math.cos(0.15), 0, 0, math.sin(0.15)], atol=1e-6)
    ring = node(viewer, "/robots/r1/position/ellipse").points
    assert ring.shape == (24, 2, 3)  # around the robot: 3 sigma of sqrt(1e-4 m^2) = 3 cm
    radii = np.hypot(ring[:, 0, 0], ring[:, 0, 1])
    s_min = np.hypot(0.03, 0.02)  # with the 2 cm floor added in quadrature
    assert radii.min() == pytest.approx(s_min, rel=1e-3)
    foot = node(viewer, "/robots/r1/position/body/footprint").points
    assert foot.shape == (48, 2, 3)  # 12 border pixels per edge, closed
    np.testing.assert_allclose(foot[..., 2], 2.5 - 0.125, atol=1e-3)  # ceiling, body frame
    cam = site.robots()[0].camera
    reach = (2.5 - cam.T_body_camera[2, 3]) * math.tan(math.radians(40.0))  # usable angle
    offset = np.hypot(
        foot[..., 0] - cam.T_body_camera[0, 3], foot[..., 1] - cam.T_body_camera[1, 3]
    )
    assert offset.max() <= reach + 1e-6
    rays = node(viewer, "/robots/r1/rays").points
    pose = site.robots()[0].pose
    assert pose is not None
    used = pose.landmark_ids
    assert len(rays) == len(used) >= 2
    np.testing.assert_allclose(
        np.sort(rays[:, 1, 0]), np.sort([site.truth[i][0] for i in used]), atol=1e-3
    )


def test_map_edits_and_leds_reach_the_scene(site_viewer: tuple[MemSite, Viewer]) -> None:
    site, viewer = site_viewer
    scene = viewer.scene
    assert scene is not None
    site.delete_landmark(10, actor="t")
    site.add_landmark(99, 4.0, 4.0, 2.6, actor="t")
    site.set_leds(frozenset({11}), actor="t")
    wait_for(lambda: 99 in scene.landmark_ids() and 10 not in scene.landmark_ids())
    wait_for(lambda: scene.is_lit(11) and not scene.is_lit(12))
    h = node(viewer, "/landmarks/99")
    np.testing.assert_allclose(h.position, [4.0, 4.0, 2.6])


def test_tickets_are_single_use(site_viewer: tuple[MemSite, Viewer]) -> None:
    from web.roles import Session

    _, viewer = site_viewer
    t1 = viewer.issue_ticket(Session("admin", "viewer:key:1"))
    t2 = viewer.issue_ticket(Session("viewer", "viewer:key:2"))
    assert t1 != t2 and len(t1) >= 24
