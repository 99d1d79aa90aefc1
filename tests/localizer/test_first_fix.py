"""The first fix from sightings carried by odometry (localizer/first_fix.py)."""

from __future__ import annotations

import numpy as np

from localizer.camera import T_body_camera_upward, predict_pixels
from localizer.first_fix import consistent_fix, first_fix, transfer_pixel
from localizer.geometry import T_world_body_from_pose
from localizer.identification import Sighting
from localizer.landmark_map import LandmarkMap
from sim.cameras import wide_angle_camera

CAM = wide_angle_camera(
    "fisheye", T_body_camera=T_body_camera_upward(yaw=1.2, offset_xy=(0.1, -0.05))
)
MAP = LandmarkMap(
    np.array([1, 2, 3]), np.array([[0.0, 0.0, 2.5], [1.2, 0.0, 2.5], [0.6, 1.0, 2.45]])
)


def _pixel(pose: tuple[float, float, float], row: int) -> tuple[float, float]:
    px, _ = predict_pixels(CAM, T_world_body_from_pose(*pose), MAP.positions[[row]])
    return float(px[0, 0]), float(px[0, 1])


def test_a_spot_carried_by_odometry_lands_where_the_new_pose_sees_it() -> None:
    then, now = (0.4, 0.3, 0.2), (0.7, 0.45, 0.9)
    for row in range(3):
        moved = transfer_pixel(CAM, _pixel(then, row), MAP.positions[row, 2], then, now)
        np.testing.assert_allclose(moved, _pixel(now, row), atol=1e-6)


def test_sightings_from_different_frames_give_the_current_pose() -> None:
    track = {0: (0.4, 0.3, 0.2), 10: (0.5, 0.35, 0.4), 20: (0.6, 0.4, 0.6)}
    sightings = [Sighting(1, 0, _pixel(track[0], 0)), Sighting(2, 10, _pixel(track[10], 1))]
    fix = first_fix(
        CAM, MAP, sightings, track.__getitem__, 20, pixel_sigma_px=1.0, max_residual_px=2.0
    )
    assert fix is not None
    np.testing.assert_allclose([fix.x, fix.y, fix.theta], track[20], atol=1e-6)


def test_one_spoiled_sighting_of_three_is_left_out() -> None:
    pose = (0.5, 0.4, -0.3)
    pixels = np.array([_pixel(pose, r) for r in range(3)])
    pixels[2] += (25.0, -10.0)  # a stray source taken for landmark 3
    fix = consistent_fix(
        CAM, pixels, MAP.positions, (1, 2, 3), pixel_sigma_px=1.0, max_residual_px=2.0
    )
    assert fix is not None and fix.landmark_ids == (1, 2)
    np.testing.assert_allclose([fix.x, fix.y, fix.theta], pose, atol=1e-6)


def test_a_sighting_older_than_the_odometry_history_is_carried_from_its_own_pose() -> None:
    # Seen 20 s ago; the odometry kept since then no longer reaches back (it answers with
    # its oldest pose): the sighting's own odometry pose carries it, the fix is right.
    track = {0: (0.4, 0.3, 0.2), 19 * 10**9: (2.9, 1.1, 0.5), 20 * 10**9: (3.0, 1.2, 0.6)}
    far = LandmarkMap(np.array([1, 2]), np.array([[0.0, 0.0, 2.5], [3.6, 1.5, 2.5]]))
    old = Sighting(1, 0, _pixel_in(far, track[0], 0), odometry=track[0])
    new = Sighting(2, 19 * 10**9, _pixel_in(far, track[19 * 10**9], 1))

    def expired(t_ns: int) -> tuple[float, float, float]:
        return track[t_ns] if t_ns >= 19 * 10**9 else track[19 * 10**9]

    kw = {"pixel_sigma_px": 1.0, "max_residual_px": 2.0}
    fix = first_fix(CAM, far, [old, new], expired, 20 * 10**9, **kw)  # type: ignore[arg-type]
    assert fix is not None
    np.testing.assert_allclose([fix.x, fix.y, fix.theta], track[20 * 10**9], atol=1e-6)
    bare = Sighting(1, 0, old.pixel)  # looked up instead: from the wrong pose, no fix
    assert first_fix(CAM, far, [bare, new], expired, 20 * 10**9, **kw) is None  # type: ignore[arg-type]


def _pixel_in(lmap: LandmarkMap, pose: tuple[float, float, float], row: int) -> tuple[float, float]:
    px, ok = predict_pixels(CAM, T_world_body_from_pose(*pose), lmap.positions[[row]])
    assert ok[0]
    return float(px[0, 0]), float(px[0, 1])
