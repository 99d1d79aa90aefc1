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
