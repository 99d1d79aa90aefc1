from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np
import viser

from tests.web.memsite import grid_site
from web.scene import SceneConfig, SiteScene, Trail


def node(server: viser.ViserServer, name: str) -> Any:
    h = server.scene.get_handle_by_name(name)
    assert h is not None, name
    return h


def test_trail_pieces_join_up_and_the_oldest_goes(server: viser.ViserServer) -> None:
    trail = Trail(server.scene, "/t", piece=3, max_points=6)  # 2 pieces of 3 points
    for k in range(7):
        trail.append(float(k), 0.0)
    pieces = trail.pieces
    assert len(pieces) == 2
    # piece 1 held points 0-2, piece 2 points 2-4, piece 3 points 4-6: piece 1 removed
    np.testing.assert_allclose(pieces[0].points[:, :, 0], [[2, 3], [3, 4]])
    np.testing.assert_allclose(pieces[1].points[:, :, 0], [[4, 5], [5, 6]])
    assert server.scene.get_handle_by_name("/t/1") is None
    assert pieces[1].colors.shape == (2, 2, 3)


def test_a_robot_is_only_redrawn_for_a_new_estimate(server: viser.ViserServer) -> None:
    site = grid_site()
    scene = SiteScene(server, SceneConfig(rays_every=3))
    scene.update_landmarks(site.landmarks(), site.lit())
    robots = site.robots()
    assert scene.robots_changed(robots)
    scene.update_robots(robots)
    assert not scene.robots_changed(robots)
    rb = robots[0]
    assert rb.pose is not None
    moved = replace(rb, pose=replace(rb.pose, t_ns=rb.pose.t_ns + 1, x=rb.pose.x + 0.5))
    assert moved.pose is not None
    assert scene.robots_changed([moved, *robots[1:]])
    scene.update_robots([moved, *robots[1:]])
    at = node(server, f"/robots/{rb.name}/position")
    np.testing.assert_allclose(at.position, [rb.pose.x + 0.5, rb.pose.y, 0.0])
    # the landmarks used did not change: the rays wait for every third update (10 Hz)
    rays = node(server, f"/robots/{rb.name}/rays").points
    c, s = np.cos(rb.pose.theta), np.sin(rb.pose.theta)
    t = rb.camera.T_body_camera[:3, 3]
    cam_x_before = rb.pose.x + c * t[0] - s * t[1]
    np.testing.assert_allclose(rays[:, 0, 0], cam_x_before, atol=1e-5)
    for k in range(2):  # the third update redraws them from the new position
        later = replace(moved, pose=replace(moved.pose, t_ns=moved.pose.t_ns + 1 + k))
        scene.update_robots([later, *robots[1:]])
    rays = node(server, f"/robots/{rb.name}/rays").points
    np.testing.assert_allclose(rays[:, 0, 0], cam_x_before + 0.5, atol=1e-5)
