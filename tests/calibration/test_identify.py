"""Naming spots from the LED sweep and the camera's own pose."""

from __future__ import annotations

import numpy as np

from calibration.identify import identify_spots
from localizer.camera import T_body_camera_upward, predict_pixels
from localizer.geometry import T_world_body_from_pose
from sim.cameras import wide_angle_camera
from tests.calibration.test_mounting import _drive, _landmarks


def test_sweep_then_motion_names_every_visible_landmark() -> None:
    rng = np.random.default_rng(3)
    landmarks = _landmarks(rng)
    camera = wide_angle_camera(
        "fisheye", T_body_camera=T_body_camera_upward(yaw=2.0, offset_xy=(0.1, 0.05))
    )
    _, pose, t_end = _drive()
    frames = []
    truth = []
    T0 = T_world_body_from_pose(*pose(0.0))
    for k, lid in enumerate(landmarks.ids):  # the sweep, robot still
        px, valid = predict_pixels(camera, T0, landmarks.positions[k : k + 1])
        frames.append((k, px[valid], frozenset({int(lid)})))
    for t in np.arange(0.0, t_end, 0.1):
        px, valid = predict_pixels(camera, T_world_body_from_pose(*pose(t)), landmarks.positions)
        noisy = px[valid] + rng.normal(0, 0.3, (int(valid.sum()), 2))
        glint = np.array([[5.0, 5.0]])  # a reflection that is no landmark
        order = rng.permutation(len(noisy))
        frames.append((1000 + round(t * 10), np.vstack([noisy[order], glint]), None))
        truth.append(dict(zip(landmarks.ids[valid][order].tolist(), noisy[order], strict=True)))
    out = identify_spots(wide_angle_camera("fisheye"), landmarks, frames)
    moving = [d for d in out if d[0] >= 1000]
    assert len(moving) == len(truth)
    named = 0
    for (_, ids, px), true_px in zip(moving, truth, strict=True):
        # every name is right (the glint gets none); a landmark just entering at the
        # image border may stay unnamed for a frame
        for lid, p in zip(ids, px, strict=True):
            np.testing.assert_array_equal(p, true_px[lid])
        assert len(ids) >= len(true_px) - 1
        named += len(ids)
    assert named >= 0.99 * sum(len(t) for t in truth)


def test_no_sweep_and_no_pose_names_nothing() -> None:
    landmarks = _landmarks(np.random.default_rng(0))
    frames = [(0, np.array([[100.0, 100.0], [200.0, 200.0], [300.0, 100.0]]), None)]
    assert identify_spots(wide_angle_camera("fisheye"), landmarks, frames) == []
