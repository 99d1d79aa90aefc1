from __future__ import annotations

import numpy as np
import pytest

from localizer.geometry import (
    T_world_body_from_pose,
    check_transform,
    invert_transform,
    pose_from_T_world_body,
    transform_points,
    wrap_angle,
)


@pytest.mark.parametrize(
    ("angle", "expected"),
    [
        (0.0, 0.0),
        (np.pi, np.pi),
        (-np.pi, np.pi),
        (3 * np.pi, np.pi),
        (2 * np.pi + 0.1, 0.1),
        (-np.pi - 0.1, np.pi - 0.1),
        (np.pi + 1e-12, -np.pi + 1e-12),
        (3.1415926535897936, np.pi),  # a hair above pi: np.mod rounds to 2 pi
    ],
)
def test_wrap_angle_maps_into_half_open_interval(angle: float, expected: float) -> None:
    assert wrap_angle(angle) == pytest.approx(expected, abs=1e-9)
    assert -np.pi < wrap_angle(angle) <= np.pi


def test_wrap_angle_on_arrays_stays_in_range() -> None:
    rng = np.random.default_rng(1)
    a = rng.uniform(-50, 50, 1000)
    w = np.asarray(wrap_angle(a))
    assert np.all(w > -np.pi) and np.all(w <= np.pi)
    np.testing.assert_allclose(np.cos(w), np.cos(a), atol=1e-9)
    np.testing.assert_allclose(np.sin(w), np.sin(a), atol=1e-9)


def test_pose_round_trip_and_inverse() -> None:
    T = T_world_body_from_pose(1.5, -2.0, 3.1)
    assert pose_from_T_world_body(T) == pytest.approx((1.5, -2.0, 3.1))
    np.testing.assert_allclose(invert_transform(T) @ T, np.eye(4), atol=1e-12)
    p = np.array([[1.0, 0.0, 0.5]])
    np.testing.assert_allclose(
        transform_points(T, p), [[1.5 + np.cos(3.1), -2.0 + np.sin(3.1), 0.5]], atol=1e-12
    )


def test_check_transform_names_the_fault() -> None:
    bad = np.eye(4)
    bad[0, 0] = 2.0
    with pytest.raises(ValueError, match="T_BS: upper-left 3x3 block is not a rotation"):
        check_transform(bad, "T_BS")
    with pytest.raises(ValueError, match="expected a 4x4"):
        check_transform(np.eye(3), "T_BS")
