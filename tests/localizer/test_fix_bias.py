"""The consider update of fixes sharing a systematic error (`localizer.fix_bias`), and the
pose filter's use of it and of the attenuated wheel-base Jacobian: known answers."""

from __future__ import annotations

import math

import numpy as np

from localizer.fix_bias import carried_correlation, carry_bias, consider_update, moved_bias
from localizer.pose import PoseFix
from localizer.pose_filter import FilterConfig, PoseFilter

W = 0.36


def _fix(x: float, y: float, th: float, cov: np.ndarray, ids: tuple[int, ...]) -> PoseFix:
    return PoseFix(x, y, th, cov, landmark_ids=ids, n_landmarks=len(ids))


def test_without_correlation_it_is_the_kalman_update() -> None:
    rng = np.random.default_rng(1)
    A = rng.normal(size=(6, 6))
    P = A @ A.T + 0.1 * np.eye(6)
    R = np.diag([0.2, 0.3, 0.1])
    y = np.array([0.1, -0.2, 0.05])
    found = consider_update(P.tolist(), np.zeros((6, 3)).tolist(), y.tolist(), R.tolist(),
                            np.zeros((3, 3)).tolist())  # fmt: skip
    assert found is not None
    dX, P_new, C_new, nis = found
    S = P[:3, :3] + R
    K = P[:, :3] @ np.linalg.inv(S)
    np.testing.assert_allclose(dX, K @ y, rtol=1e-12)
    np.testing.assert_allclose(P_new, P - K @ S @ K.T, rtol=1e-10, atol=1e-12)
    assert math.isclose(nis, float(y @ np.linalg.solve(S, y)), rel_tol=1e-12)
    np.testing.assert_allclose(C_new, 0.0, atol=1e-15)


def test_repeated_fixes_with_a_common_error_do_not_average_it_away() -> None:
    """N fixes of a static state, each with white variance w and the same bias of
    variance b: the estimate's variance is b + w / N (not (b + w) / N)."""
    b, w, N = 4e-6, 1e-6, 60
    P = np.diag([1.0, 1.0, 1.0, 1e-4, 1e-4, 1e-4]).tolist()
    C = np.zeros((6, 3)).tolist()
    R_w, R_b = (w * np.eye(3)).tolist(), (b * np.eye(3)).tolist()
    for _ in range(N):
        found = consider_update(P, C, [0.0] * 3, R_w, R_b)
        assert found is not None
        _, P, C, _ = found
    np.testing.assert_allclose(np.diag(P)[:3], b + w / N, rtol=0.02)
    # as white noise the filter would claim (b + w) / N, 22x smaller here
    assert (b + w) / N < 0.05 * P[0][0]


def test_the_share_of_common_landmarks_is_the_correlation() -> None:
    assert carried_correlation(frozenset({1, 2}), frozenset({1, 2})) == 1.0
    assert carried_correlation(frozenset({1, 2}), frozenset({3, 4})) == 0.0
    assert math.isclose(carried_correlation(frozenset({1, 2}), frozenset({1, 2, 3})),
                        2 / math.sqrt(6))  # fmt: skip
    assert carried_correlation(frozenset(), frozenset({1})) == 0.0


def test_a_rigid_map_error_moves_the_fix_error_with_the_body() -> None:
    """A pair's map turned by 0.01 rad and shifted about its centre: the fix from the
    map is the true pose moved by that rigid motion; between two body positions its error
    changes exactly as `moved_bias` says (to first order in the turn)."""
    d_th, shift, centre = 0.01, np.array([0.003, -0.002]), np.array([4.0, 1.5])

    def fix_error(p: np.ndarray) -> np.ndarray:
        c, s = math.cos(d_th), math.sin(d_th)
        moved = centre + np.array([[c, -s], [s, c]]) @ (p - centre) + shift
        return np.array([*(moved - p), d_th])

    a, b = np.array([3.2, 1.4]), np.array([4.9, 1.7])
    predicted = moved_bias(*(b - a)) @ fix_error(a)
    # the change itself is d_th x 1.7 m = 17 mm; what is left is second order, d_th^2 x 1.7 m
    assert abs(fix_error(b)[1] - fix_error(a)[1]) > 0.016
    np.testing.assert_allclose(predicted, fix_error(b), atol=2e-4)


def test_a_correlation_the_new_view_cannot_hold_is_read_through_its_covariance() -> None:
    """After many fixes of a large error the new view's error is 100x smaller: the
    correlation is scaled down to it (b' = L' L^-1 b), so the joint covariance stays
    positive semi-definite and the consider gain stays below one."""
    P = np.diag([1e-4, 1e-4, 1e-5, 1e-6, 1e-6, 1e-6])
    R_old = np.diag([1e-4, 1e-4, 1e-5])
    C = np.zeros((6, 3))
    C[:3, :3] = -R_old * 0.9  # as after many fixes of a large bias
    R_new = np.diag([1e-6, 1e-6, 1e-7])
    C2 = np.array(carry_bias(C.tolist(), R_old.tolist(), R_new.tolist(), 1.0, 0.0, 0.0))
    joint = np.block([[P, C2], [C2.T, R_new]])
    assert np.min(np.linalg.eigvalsh(joint)) > -1e-18
    np.testing.assert_allclose(C2, C * 0.1, atol=1e-15)  # sigma ratio 1/10
    # a new view with a larger error holds the whole correlation, scaled by rho
    C3 = carry_bias((0.01 * C).tolist(), R_old.tolist(), (np.eye(3) * 1e-3).tolist(), 0.5, 0, 0)
    np.testing.assert_allclose(np.array(C3), 0.005 * C, atol=1e-18)


def test_the_carried_correlation_moves_with_the_body_as_moved_bias_says() -> None:
    rng = np.random.default_rng(3)
    C = rng.normal(0.0, 1e-3, (6, 3))
    A = rng.normal(0.0, 0.01, (3, 3))
    R_old = A @ A.T + 1e-6 * np.eye(3)
    T = moved_bias(0.4, -0.7)
    big = 10.0 * T @ R_old @ T.T  # holds the correlation: only the rigid carry applies
    got = np.array(carry_bias(C.tolist(), R_old.tolist(), big.tolist(), 0.8, 0.4, -0.7))
    np.testing.assert_allclose(got, 0.8 * C @ T.T, rtol=1e-12)
    # and read through a smaller one: C T^T M^T with M R_c M^T = R_new
    R_new = 0.2 * T @ R_old @ T.T
    got = np.array(carry_bias(C.tolist(), R_old.tolist(), R_new.tolist(), 1.0, 0.4, -0.7))
    L, L_new = np.linalg.cholesky(T @ R_old @ T.T), np.linalg.cholesky(R_new)
    M = L_new @ np.linalg.inv(L)
    np.testing.assert_allclose(M @ T @ R_old @ T.T @ M.T, R_new, rtol=1e-9)
    np.testing.assert_allclose(got, C @ T.T @ M.T, rtol=1e-9, atol=1e-15)


def test_the_filter_keeps_a_short_pairs_heading_error_while_parked_under_it() -> None:
    """Parked under one pair for 3 s at 30 Hz (no odometry noise while parked), the pair's
    heading error 0.5 deg (survey), 0.1 deg white: the plain update claims
    sqrt((0.5^2 + 0.1^2) / 90) = 0.054 deg; the consider update sqrt(0.5^2 + 0.1^2 / 90)."""
    cfg = FilterConfig(wheel_noise_m_per_sqrt_s=0.0, wheel_slip_m_per_sqrt_m=0.0,
                       calibration_walk_per_sqrt_s=0.0, adapt_noise=False)  # fmt: skip
    sig_b, sig_w = math.radians(0.5), math.radians(0.1)
    R_b = np.diag([0.003**2, 0.003**2, sig_b**2])
    R_w = np.diag([0.0005**2, 0.0005**2, sig_w**2])
    sd = {}
    for correlated in (False, True):
        f = PoseFilter(0.0, 0.0, 0.0, np.diag([0.01, 0.01, 0.01]), wheel_base=W, config=cfg)
        for _ in range(90):
            f.predict(0.0, 0.0, 1 / 30)
            f.update_fix(_fix(0.0, 0.0, 0.0, R_b + R_w, (1, 2)),
                         white_covariance=R_w if correlated else None)  # fmt: skip
        sd[correlated] = math.degrees(math.sqrt(f.covariance[2, 2]))
    assert math.isclose(sd[False], math.sqrt((0.5**2 + 0.1**2) / 90), rel_tol=0.02)
    assert math.isclose(sd[True], math.sqrt(0.5**2 + 0.1**2 / 90), rel_tol=0.02)


def test_driving_straight_the_wheel_base_is_not_learnt_from_the_wheels_noise() -> None:
    """Straight at 1 m/s for 20 s, exact wheels with 1 % noise per 50 Hz sample, a fix of
    the true pose every 1/30 s: without the attenuation k_b is pushed up by the measured
    turn's noise, with it it stays near 1."""
    drift = {}
    for attenuate in (False, True):
        rng = np.random.default_rng(7)
        cfg = FilterConfig(attenuate_turn_scale=attenuate, adapt_noise=False)
        f = PoseFilter(0.0, 0.0, 0.0, np.diag([1e-4, 1e-4, 1e-5]), wheel_base=W, config=cfg)
        R = np.diag([0.002**2, 0.002**2, math.radians(0.2) ** 2])
        t_fix = 0.0
        for k in range(1000):
            v = 1.0 + rng.normal(0.0, 0.01, 2)
            f.predict(float(v[0]), float(v[1]), 0.02)
            t = (k + 1) * 0.02
            if t >= t_fix + 1 / 30:
                t_fix = t
                f.update_fix(_fix(t, 0.0, 0.0, R, (1, 2)))
        drift[attenuate] = f.calibration.wheel_base_scale - 1.0
    assert drift[False] > 0.01  # the bias the attenuation removes
    assert abs(drift[True]) < 0.3 * drift[False]
