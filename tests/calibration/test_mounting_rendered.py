"""Mounting calibration through the whole chain: rendered IR frames, `detect_spots`, then
the estimate. Spots are identified by their nearest predicted landmark (a stand-in for the
localizer's identification)."""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial import cKDTree

from calibration.mounting import mounting_from_observations
from localizer.camera import T_body_camera_upward, predict_pixels
from localizer.geometry import T_world_body_from_pose
from localizer.spots import DetectionConfig, detect_spots
from sim.cameras import wide_angle_camera
from sim.render import render_frame
from tests.calibration.test_mounting import WHEEL_BASE, _drive, _landmarks


def test_rendered_frames_recover_the_mounting() -> None:
    rng = np.random.default_rng(21)
    offset = (-0.1, 0.0)
    camera = wide_angle_camera(
        "fisheye", T_body_camera=T_body_camera_upward(yaw=math.pi / 2, offset_xy=offset)
    )
    landmarks = _landmarks(rng)
    odo, pose, t_end = _drive()
    detections = []
    config = DetectionConfig()
    for t in np.arange(0.0, t_end, 0.2):
        T_wb = T_world_body_from_pose(*pose(t))
        frame = render_frame(camera, T_wb, landmarks.positions, np.ones(len(landmarks)), rng=rng)
        spots = detect_spots(frame, config)
        predicted, valid = predict_pixels(camera, T_wb, landmarks.positions)
        dist, idx = cKDTree(predicted[valid]).query(spots.pixels)
        ok = dist < 3.0
        detections.append((round(t * 1e9), landmarks.ids[valid][idx[ok]], spots.pixels[ok]))
    assert np.mean([len(d[1]) for d in detections]) > 6
    result = mounting_from_observations(
        wide_angle_camera("fisheye"), landmarks, detections, odo, wheel_base_m=WHEEL_BASE
    )
    assert abs(math.degrees(result.yaw_rad) - 90.0) < 0.3
    np.testing.assert_allclose(result.offset_xy_m, offset, atol=0.005)
