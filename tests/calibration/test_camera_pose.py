"""Camera pose from landmarks (PnP through the lens model)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from calibration.camera_pose import camera_pose_from_landmarks
from localizer.camera import T_body_camera_upward, predict_pixels
from localizer.geometry import T_world_body_from_pose
from sim.cameras import wide_angle_camera

LANDMARKS = np.array(
    [[0.0, 0.0, 2.5], [1.0, 0.2, 2.6], [0.3, 1.1, 2.4], [-0.8, 0.4, 2.55], [0.5, -0.9, 2.7]]
)


@pytest.mark.parametrize("lens", ["fisheye", "pinhole"])
@pytest.mark.parametrize("count", [3, 4, 5])
def test_recovers_the_camera_pose(lens: str, count: int) -> None:
    T_bc = T_body_camera_upward(yaw=0.7, offset_xy=(0.05, -0.03), height=0.3, tilt_xy=(0.02, 0.0))
    camera = wide_angle_camera(lens, T_body_camera=T_bc)  # type: ignore[arg-type]
    T_wb = T_world_body_from_pose(0.2, 0.3, 2.5)
    px, valid = predict_pixels(camera, T_wb, LANDMARKS[:count])
    assert valid.all()
    pose = camera_pose_from_landmarks(camera, px, LANDMARKS[:count])
    assert pose is not None
    np.testing.assert_allclose(pose.T_world_camera, T_wb @ T_bc, atol=1e-6)
    assert pose.residual_rms_px < 1e-6 and pose.count == count


def test_noisy_pixels_give_a_close_pose() -> None:
    camera = wide_angle_camera("fisheye")
    T_wb = T_world_body_from_pose(-0.1, 0.2, -1.0)
    px, _ = predict_pixels(camera, T_wb, LANDMARKS)
    rng = np.random.default_rng(4)
    pose = camera_pose_from_landmarks(camera, px + rng.normal(0, 0.3, px.shape), LANDMARKS)
    assert pose is not None
    T_true = T_wb @ camera.T_body_camera
    assert (
        np.linalg.norm(pose.T_world_camera[:3, 3] - T_true[:3, 3]) < 0.03
    )  # tilt trades against x-y
    assert 0.05 < pose.residual_rms_px < 0.5


def test_too_few_or_mismatched_landmarks() -> None:
    camera = wide_angle_camera("fisheye")
    assert camera_pose_from_landmarks(camera, np.zeros((2, 2)), LANDMARKS[:2]) is None
    with pytest.raises(ValueError, match="3 pixels but 2 landmark positions"):
        camera_pose_from_landmarks(camera, np.zeros((3, 2)), LANDMARKS[:2])
    assert math.isfinite(camera.fu)
