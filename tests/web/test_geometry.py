from __future__ import annotations

import math
from typing import Literal

import numpy as np
import pytest

from commissioning.geometry import landmark_from_spot
from localizer.camera import T_body_camera_upward, predict_pixels
from localizer.geometry import T_world_body_from_pose
from sim.cameras import wide_angle_camera
from web.geometry import camera_footprint, ellipse_axes, ellipse_points, ray_plane_point


def test_ellipse_axes_of_a_rotated_covariance() -> None:
    angle = 0.4
    R = np.array([[math.cos(angle), -math.sin(angle)], [math.sin(angle), math.cos(angle)]])
    cov = R @ np.diag([0.04, 0.01]) @ R.T
    a, b, phi = ellipse_axes(cov, n_sigma=2.0)
    np.testing.assert_allclose([a, b, phi], [0.4, 0.2, angle], atol=1e-12)


def test_ellipse_points_lie_on_the_n_sigma_contour() -> None:
    cov = np.array([[0.09, 0.02], [0.02, 0.04]])
    pts = ellipse_points([1.0, -2.0], cov, n_sigma=3.0, n_points=40)
    assert pts.shape == (41, 2)
    d = pts - [1.0, -2.0]
    mahal = np.einsum("ni,ij,nj->n", d, np.linalg.inv(cov), d)
    np.testing.assert_allclose(mahal, 9.0, rtol=1e-9)
    np.testing.assert_allclose(pts[0], pts[-1])


def test_ellipse_axes_refuses_bad_matrices() -> None:
    with pytest.raises(ValueError, match="2x2"):
        ellipse_axes(np.eye(3))
    with pytest.raises(ValueError, match="symmetric"):
        ellipse_axes([[1.0, 0.5], [0.0, 1.0]])
    with pytest.raises(ValueError, match="2x2"):
        ellipse_axes([[np.nan, 0.0], [0.0, 1.0]])


def test_ray_plane_point() -> None:
    p = ray_plane_point([1.0, 2.0, 10.0], [0.5, 0.0, -1.0], 2.5)
    assert p is not None
    np.testing.assert_allclose(p, np.array([4.75, 2.0, 2.5]))
    assert ray_plane_point([0, 0, 0], [1, 0, 0], 2.5) is None
    assert ray_plane_point([0, 0, 3], [0, 0, 1], 2.5) is None


@pytest.mark.parametrize("lens", ["pinhole", "fisheye"])
def test_landmark_from_spot_inverts_predict_pixels(lens: Literal["pinhole", "fisheye"]) -> None:
    cam = wide_angle_camera(lens, T_body_camera=T_body_camera_upward(offset_xy=(0.1, 0.0)))
    x, y, theta = 3.0, -1.0, 2.5
    truth = np.array([[3.6, -0.7, 2.55]])
    px, valid = predict_pixels(cam, T_world_body_from_pose(x, y, theta), truth)
    assert valid[0]
    p = landmark_from_spot(cam, x, y, theta, px[0], 2.55)
    assert p is not None
    np.testing.assert_allclose(p, truth[0], atol=1e-6)


def test_camera_footprint_border_projects_to_the_image_border() -> None:
    cam = wide_angle_camera("pinhole")
    x, y, theta, h = 1.0, 2.0, 0.7, 2.5
    poly = camera_footprint(cam, x, y, theta, h, per_edge=5)
    assert poly.shape == (21, 3)
    np.testing.assert_allclose(poly[:, 2], h)
    px, _ = predict_pixels(cam, T_world_body_from_pose(x, y, theta), poly[:-1])
    # every vertex lands on the image border (col or row at the edge)
    edge = np.minimum.reduce(
        [np.abs(px[:, 0] + 0.5), np.abs(px[:, 0] - 639.5), np.abs(px[:, 1] + 0.5),
         np.abs(px[:, 1] - 479.5)]
    )  # fmt: skip
    np.testing.assert_allclose(edge, 0.0, atol=1e-3)
    # the centre of the footprint is above the camera (offset 0: above the robot)
    np.testing.assert_allclose(poly[:-1, :2].mean(axis=0), [x, y], atol=0.05)
