"""The usable camera footprint: the lens's usable angle and the site's walls."""

from __future__ import annotations

import math

import numpy as np
import pytest

from localizer.camera import CameraModel
from web.footprint import (
    clamp_off_axis,
    clip_polygon_to_rect,
    footprint_in_site,
    usable_footprint_body,
)


def _area(poly: np.ndarray) -> float:
    x, y = poly[:, 0], poly[:, 1]
    return 0.5 * abs(float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))))


def _fisheye() -> CameraModel:
    """An upward equidistant fisheye of 190 degrees (its border rays reach the horizon)."""
    T = np.eye(4)
    T[:3, 3] = (0.1, 0.0, 0.3)
    return CameraModel(
        width=640, height=480, fu=160.0, fv=160.0, cu=320.0, cv=240.0,
        distortion_model="equidistant", distortion=np.zeros(4), T_body_camera=T,
    )  # fmt: skip


def test_rays_beyond_the_usable_angle_are_pulled_in_keeping_their_azimuth() -> None:
    rays = np.array([[0.0, 0.0, 1.0], [1.0, 1.0, 0.1], [0.0, -1.0, -0.5]])
    out = clamp_off_axis(rays, math.radians(40.0))
    angles = np.degrees(np.arccos(out[:, 2]))
    np.testing.assert_allclose(angles, [0.0, 40.0, 40.0], atol=1e-9)
    np.testing.assert_allclose(np.arctan2(out[1:, 1], out[1:, 0]), [math.pi / 4, -math.pi / 2])


def test_a_wide_lens_footprint_stops_at_the_usable_angle() -> None:
    cam = _fisheye()
    foot = usable_footprint_body(cam, 2.5, max_off_axis_rad=math.radians(40.0))
    r = np.hypot(foot[:, 0] - 0.1, foot[:, 1])
    assert r.max() == pytest.approx((2.5 - 0.3) * math.tan(math.radians(40.0)), rel=1e-6)
    np.testing.assert_allclose(foot[:, 2], 2.5)
    assert np.array_equal(foot[0], foot[-1])


def test_clipping_to_the_site_keeps_the_inside_part() -> None:
    square = np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0], [-1.0, -1.0]])
    half = clip_polygon_to_rect(square, (0.0, 5.0, -5.0, 5.0))
    assert _area(half) == pytest.approx(2.0)
    assert half[:, 0].min() == pytest.approx(0.0)
    assert len(clip_polygon_to_rect(square, (2.0, 3.0, 2.0, 3.0))) == 0
    foot = np.column_stack([square, np.full(5, 2.2)])
    assert footprint_in_site(foot, 0.0, 0.0, 0.3, (-5.0, 5.0, -5.0, 5.0)) is None  # inside
    # robot 0.5 m from the wall at x = 0, facing +y: the part beyond the wall is cut off,
    # returned in the body frame (x_body = y_world ... turned by -90 degrees)
    clipped = footprint_in_site(foot, 0.5, 0.0, math.pi / 2, (0.0, 5.0, -5.0, 5.0))
    assert clipped is not None and np.array_equal(clipped[0], clipped[-1])
    assert _area(clipped[:-1]) == pytest.approx(1.5 * 2.0)
    np.testing.assert_allclose(clipped[:, 2], 2.2)
    assert clipped[:, 1].max() == pytest.approx(0.5)  # body +y points to world -x (the wall)
