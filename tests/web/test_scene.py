from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np
import viser

from tests.web.memsite import grid_site
from web.scene import SceneConfig, SiteScene
from web.trail import Trail, TrailConfig


def node(server: viser.ViserServer, name: str) -> Any:
    h = server.scene.get_handle_by_name(name)
    assert h is not None, name
    return h


def test_trail_pieces_join_up_and_the_oldest_goes(server: viser.ViserServer) -> None:
    cfg = TrailConfig(min_step_m=0.1, max_jump_m=1.0, max_gap_s=1.5, max_points=6, piece=3)
    trail = Trail(server.scene, "/t", color=(1, 2, 3), config=cfg)
    for k in range(7):
        assert trail.append(0.5 * k, 0.0, 0.1 * k)
    pieces = trail.pieces
    assert len(pieces) == 2
    # piece 1 held points 0-2, piece 2 points 2-4, piece 3 points 4-6: piece 1 removed
    np.testing.assert_allclose(pieces[0].points[:, :, 0], [[1.0, 1.5], [1.5, 2.0]])
    np.testing.assert_allclose(pieces[1].points[:, :, 0], [[2.0, 2.5], [2.5, 3.0]])
    assert server.scene.get_handle_by_name("/t/1") is None
    assert pieces[1].colors.shape == (2, 2, 3) and tuple(pieces[1].colors[0, 0]) == (1, 2, 3)


def test_trail_samples_by_distance_and_breaks_at_gaps(server: viser.ViserServer) -> None:
    """A robot standing still adds nothing; a jump in space (a busy server's late update, a
    robot found again) or in time starts a piece of its own: no chord through the walls."""
    trail = Trail(server.scene, "/g", config=TrailConfig(min_step_m=0.1, max_jump_m=1.0))
    assert trail.append(0.0, 0.0, 0.0)
    assert not trail.append(0.05, 0.0, 0.1)  # 5 cm: not yet
    assert trail.append(0.5, 0.0, 0.2)
    assert trail.append(6.5, 0.0, 0.4)  # 6 m in 0.2 s: a gap in the poses
    assert trail.append(7.0, 0.0, 0.6)
    assert trail.append(7.5, 0.0, 9.0)  # 8 s later: a gap in time
    segs = np.concatenate([p.points for p in trail.pieces if len(p.points)])
    lengths = np.hypot(*(segs[:, 1, :2] - segs[:, 0, :2]).T)
    assert len(trail.pieces) == 3 and lengths.max() <= 0.5 + 1e-6, segs


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


def test_landmark_changes_in_place_and_robot_labels_say_robot(server: viser.ViserServer) -> None:
    """A battery reading or LED switch changes the landmark's nodes in place (removing and
    re-adding them made the labels flicker at 2 Hz); robot labels read "robot r1", beside
    the robot, not a bare name a landmark ID could run into ("r3" over "201": "r301")."""
    site = grid_site()
    scene = SiteScene(server)
    lms = site.landmarks()
    scene.update_landmarks(lms, frozenset())
    sphere, label = node(server, "/landmarks/17"), node(server, "/landmarks/17/label")
    changed = [replace(lm, percent=10.0, reachable=False) if lm.id == 17 else lm for lm in lms]
    scene.update_landmarks(changed, frozenset({17}))
    assert node(server, "/landmarks/17") is sphere and node(server, "/landmarks/17/label") is label
    assert tuple(sphere.color) != (150, 150, 150) and label.text == "17 unreachable"
    assert node(server, "/landmarks/17/glow").visible
    scene.update_robots(site.robots())
    name = site.robots()[0].name
    rl = node(server, f"/robots/{name}/position/label")
    assert rl.text == f"robot {name}" and rl.position[0] > 0.2
