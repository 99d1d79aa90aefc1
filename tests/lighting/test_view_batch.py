"""The planner's one projection for all of a robot's motion samples gives exactly what a
projection per pose gives (pinhole and fisheye lenses, landmarks behind and beside)."""

from __future__ import annotations

from typing import Literal

import numpy as np
import pytest

from lighting.camera_view import body_pose, project_from_poses, visible
from localizer.camera import predict_pixels
from sim.cameras import wide_angle_camera


@pytest.mark.parametrize("lens", ["pinhole", "fisheye"])
def test_one_projection_for_many_poses_equals_one_per_pose(
    lens: Literal["pinhole", "fisheye"],
) -> None:
    cam = wide_angle_camera(lens)
    rng = np.random.default_rng(3)
    positions = np.column_stack([rng.uniform(-8, 8, 300), rng.uniform(-8, 8, 300),
                                 rng.uniform(2.0, 3.5, 300)])  # fmt: skip
    poses = [(float(x), float(y), float(t)) for x, y, t in rng.uniform(-4, 4, (16, 3))]
    px, valid = project_from_poses(cam, poses, positions)
    ok, centre = visible(cam, px, valid, 0.3, 2.5)
    for j, pose in enumerate(poses):
        one_px, one_valid = predict_pixels(cam, body_pose(*pose), positions)
        np.testing.assert_array_equal(valid[j], one_valid)
        np.testing.assert_allclose(px[j][one_valid], one_px[one_valid], atol=1e-9)
        ok_j, centre_j = visible(cam, one_px[None], one_valid[None], 0.3, 2.5)
        np.testing.assert_array_equal(ok[j], ok_j[0])
        np.testing.assert_allclose(centre[j][ok[j]], centre_j[0][ok[j]], atol=1e-9)
    assert 0 < ok.sum() < ok.size  # some seen, some not: the test says something
