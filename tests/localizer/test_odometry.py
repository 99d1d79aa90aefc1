from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

from localizer.odometry import (
    integrate_arc,
    integrate_odometry,
    odometry_increments,
    odometry_partials,
)

W = 0.36
Step = Callable[..., tuple[Any, Any, Any]]


def test_increments_are_eq_6() -> None:
    dT, dR = odometry_increments(0.2, 0.4, 0.1, W)
    assert dT == pytest.approx(0.03)
    assert dR == pytest.approx(0.2 / W * 0.1)


@pytest.mark.parametrize("step", [integrate_odometry, integrate_arc])
def test_straight_line_moves_along_heading(step: Step) -> None:
    x, y, th = step(1.0, 2.0, 0.5, 0.3, 0.3, 2.0, W)
    np.testing.assert_allclose(
        [x, y, th], [1.0 + 0.6 * math.cos(0.5), 2.0 + 0.6 * math.sin(0.5), 0.5]
    )


@pytest.mark.parametrize("step", [integrate_odometry, integrate_arc])
def test_turn_in_place_keeps_position(step: Step) -> None:
    x, y, th = step(1.0, 2.0, 0.0, -0.1, 0.1, 1.0, W)
    np.testing.assert_allclose([x, y, th], [1.0, 2.0, 0.2 / W], atol=1e-15)


def test_midpoint_formula_matches_eq_5_by_hand() -> None:
    x, y, th, vl, vr, dt = 0.5, -1.0, 1.0, 0.2, 0.5, 0.4
    dT = (vl + vr) / 2 * dt
    dR = (vr - vl) / W * dt
    got = integrate_odometry(x, y, th, vl, vr, dt, W)
    want = (x + dT * math.cos(th + dR / 2), y + dT * math.sin(th + dR / 2), th + dR)
    np.testing.assert_allclose(got, want, rtol=1e-15)


def test_arc_is_exact_on_a_circle() -> None:
    # Constant speeds: radius R = W/2 (vr + vl)/(vr - vl); a quarter turn in one step.
    vl, vr = 0.1, 0.3
    R = W / 2 * (vr + vl) / (vr - vl)
    dt = (math.pi / 2) / ((vr - vl) / W)
    x, y, th = integrate_arc(0.0, 0.0, 0.0, vl, vr, dt, W)
    np.testing.assert_allclose([x, y, th], [R, R, math.pi / 2], atol=1e-12)


def test_many_small_midpoint_steps_converge_to_the_arc() -> None:
    vl, vr, T, n = 0.2, 0.35, 3.0, 3000
    state = (0.0, 0.0, 0.3)
    for _ in range(n):
        state = integrate_odometry(*state, vl, vr, T / n, W)
    exact = integrate_arc(0.0, 0.0, 0.3, vl, vr, T, W)
    np.testing.assert_allclose(state[:2], exact[:2], atol=1e-9)
    assert float(state[2]) == pytest.approx(float(exact[2]), abs=1e-12)


def test_arc_straight_line_limit_is_continuous() -> None:
    a = integrate_arc(0.0, 0.0, 0.0, 0.5, 0.5 + 1e-12, 1.0, W)
    b = integrate_arc(0.0, 0.0, 0.0, 0.5, 0.5, 1.0, W)
    np.testing.assert_allclose(a, b, atol=1e-11)


@pytest.mark.parametrize("step", [integrate_odometry, integrate_arc])
def test_heading_wraps_across_pi(step: Step) -> None:
    _, _, th = step(0.0, 0.0, math.pi - 0.01, -0.1, 0.1, 0.1, W)
    assert th == pytest.approx(math.pi - 0.01 + 0.2 / W * 0.1 - 2 * math.pi)
    assert -math.pi < th <= math.pi


def test_vectorised_matches_scalar() -> None:
    rng = np.random.default_rng(3)
    n = 50
    args = [rng.normal(size=n), rng.normal(size=n), rng.uniform(-4, 4, n)]
    vl, vr = rng.uniform(-1, 1, n), rng.uniform(-1, 1, n)
    for step in (integrate_odometry, integrate_arc):
        xs, ys, ths = step(*args, vl, vr, 0.05, W)
        for i in range(0, n, 7):
            one = step(args[0][i], args[1][i], args[2][i], vl[i], vr[i], 0.05, W)
            np.testing.assert_allclose([xs[i], ys[i], ths[i]], one, atol=1e-12)


def test_partials_match_finite_differences() -> None:
    th, dT, dR = 2.9, 0.07, 0.05

    def xy(t: float, T: float, R: float) -> np.ndarray:
        # eq. (5) written with the increments of eq. (6) as the inputs
        return np.array([T * math.cos(t + R / 2), T * math.sin(t + R / 2)])

    xT, yT, xR, yR = odometry_partials(th, dT, dR)
    h = 1e-7
    np.testing.assert_allclose(
        [xT, yT], (xy(th, dT + h, dR) - xy(th, dT - h, dR)) / (2 * h), atol=1e-8
    )
    np.testing.assert_allclose(
        [xR, yR], (xy(th, dT, dR + h) - xy(th, dT, dR - h)) / (2 * h), atol=1e-8
    )
    d_theta = (xy(th + h, dT, dR) - xy(th - h, dT, dR)) / (2 * h)
    np.testing.assert_allclose(d_theta, [2 * xR, 2 * yR], atol=1e-8)
    # and eq. (5) itself uses exactly these increments
    x, y, _ = integrate_odometry(0.0, 0.0, th, 0.3, 0.4, 0.2, W)
    dT6, dR6 = odometry_increments(0.3, 0.4, 0.2, W)
    np.testing.assert_allclose([x, y], xy(th, dT6, dR6), atol=1e-15)
