from __future__ import annotations

import math

import numpy as np
import pytest

from localizer.odometry import integrate_arc
from survey.odometry_chain import (
    between,
    compose,
    dead_reckoning,
    relative_motions,
    segment_lengths,
    wheel_intervals,
)

NS = 1_000_000_000


def test_straight_drive_splits_exactly_at_keyframes() -> None:
    t = np.arange(0, 11) * NS // 10  # 10 Hz for 1 s at 0.5 m/s
    v = np.full((11, 2), 0.5)
    keys = np.array([0, 250_000_000, 600_000_000, NS])
    w = wheel_intervals(t, v, keys)
    d = relative_motions(w, 0.36)
    np.testing.assert_allclose(d[:, 0], [0.125, 0.175, 0.2], atol=1e-12)
    np.testing.assert_allclose(d[:, 1:], 0.0, atol=1e-12)
    dist, turn = segment_lengths(w)
    np.testing.assert_allclose(dist, [0.125, 0.175, 0.2], atol=1e-12)
    np.testing.assert_allclose(turn, 0.0, atol=1e-12)


def test_constant_turn_matches_the_exact_arc() -> None:
    W = 0.36
    t = np.arange(0, 101) * NS // 100
    v = np.tile([0.2, 0.4], (101, 1))
    w = wheel_intervals(t, v, np.array([0, NS]))
    d = relative_motions(w, W)[0]
    x, y, th = integrate_arc(0.0, 0.0, 0.0, 0.2, 0.4, 1.0, W)
    np.testing.assert_allclose(d, [x, y, th], atol=1e-6)


def test_wheel_calibration_scales_distance_and_turn() -> None:
    t = np.arange(0, 101) * NS // 100
    v = np.tile([0.3, 0.3], (101, 1))
    w = wheel_intervals(t, v, np.array([0, NS]))
    d = relative_motions(w, 0.36, scale_left=1.01, scale_right=0.99)[0]
    # equal wheel speeds, unequal scales: a slight right-hand arc (left wheel rolls farther)
    assert d[2] == pytest.approx((0.99 - 1.01) * 0.3 / 0.36, rel=1e-9)
    assert d[0] == pytest.approx(0.3, rel=1e-4)
    d2 = relative_motions(w, 0.36, base_scale=2.0)[0]
    assert d2[2] == pytest.approx(0.0, abs=1e-15)


def test_compose_between_and_dead_reckoning_round_trip() -> None:
    rng = np.random.default_rng(3)
    a = rng.uniform(-2, 2, (20, 3))
    b = rng.uniform(-2, 2, (20, 3))
    np.testing.assert_allclose(compose(a, between(a, b)), b, atol=1e-12)
    deltas = rng.uniform(-0.1, 0.1, (5, 3))
    poses = dead_reckoning((1.0, 2.0, math.pi / 3), deltas)
    np.testing.assert_allclose(between(poses[:-1], poses[1:]), deltas, atol=1e-12)


def test_bad_keyframes_and_no_samples_are_refused() -> None:
    with pytest.raises(ValueError, match="increasing"):
        wheel_intervals(np.array([0]), np.zeros((1, 2)), np.array([5, 5]))
    with pytest.raises(ValueError, match="no odometry"):
        wheel_intervals(np.zeros(0, dtype=np.int64), np.zeros((0, 2)), np.array([0, 1]))
