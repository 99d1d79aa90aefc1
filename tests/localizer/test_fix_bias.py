"""The consider update of fixes sharing a systematic error (`localizer.fix_bias`), and the
pose filter's use of it and of the attenuated wheel-base Jacobian: known answers."""

from __future__ import annotations

import math

import numpy as np

from localizer.filter_config import FilterConfig
from localizer.fix_bias import carried_correlation, carry_bias, consider_update, moved_bias
from localizer.pose import PoseFix
from localizer.pose_filter import PoseFilter

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


def test_the_float_update_is_the_consider_update_on_numpy() -> None:
    """With a cross-covariance C: the float code against the module docstring's equations
    on numpy (S = H P H^T + H C + C^T H^T + Sigma_b + R_w, K = (P H^T + C) S^-1,
    P - K S K^T, C - K (H C + Sigma_b)), for a joint covariance that is positive definite."""
    rng = np.random.default_rng(7)
    A = rng.normal(size=(9, 9))
    J = A @ A.T + 0.1 * np.eye(9)  # joint covariance of (state error, b)
    P, C, R_b = J[:6, :6], J[:6, 6:], J[6:, 6:]
    R_w = np.diag([0.2, 0.3, 0.1])
    y = np.array([0.1, -0.2, 0.05])
    found = consider_update(P.tolist(), C.tolist(), y.tolist(), R_w.tolist(), R_b.tolist())
    assert found is not None
    dX, P_new, C_new, nis = found
    H = np.hstack([np.eye(3), np.zeros((3, 3))])
    S = H @ P @ H.T + H @ C + C.T @ H.T + R_b + R_w
    K = (P @ H.T + C) @ np.linalg.inv(S)
    np.testing.assert_allclose(dX, K @ y, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(P_new, P - K @ S @ K.T, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(C_new, C - K @ (H @ C + R_b), rtol=1e-10, atol=1e-12)
    assert np.array_equal(np.array(P_new), np.array(P_new).T)
    assert math.isclose(nis, float(y @ np.linalg.solve(S, y)), rel_tol=1e-12)


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


def test_a_smaller_new_error_keeps_only_the_common_part_of_the_correlation() -> None:
    """After many fixes of a large error the new view's error is 100x smaller: only the
    part of the old error that the new view shares is carried, Cov(b_c, b') = R_new
    (lambda = 0.01: C' = 0.01 C), so the joint covariance stays positive semi-definite."""
    P = np.diag([1e-4, 1e-4, 1e-5, 1e-6, 1e-6, 1e-6])
    R_old = np.diag([1e-4, 1e-4, 1e-5])
    C = np.zeros((6, 3))
    C[:3, :3] = -R_old * 0.9  # as after many fixes of a large bias
    R_new = np.diag([1e-6, 1e-6, 1e-7])
    C2 = np.array(carry_bias(C.tolist(), R_old.tolist(), R_new.tolist(), 1.0, 0.0, 0.0))
    joint = np.block([[P, C2], [C2.T, R_new]])
    assert np.min(np.linalg.eigvalsh(joint)) > -1e-18
    np.testing.assert_allclose(C2, C * 0.01, atol=1e-15)
    # a new view with a larger error holds the whole correlation, scaled by rho
    C3 = carry_bias((0.01 * C).tolist(), R_old.tolist(), (np.eye(3) * 1e-3).tolist(), 0.5, 0, 0)
    np.testing.assert_allclose(np.array(C3), 0.005 * C, atol=1e-18)


def test_a_shrinking_error_does_not_carry_the_pose_beyond_the_new_fix() -> None:
    """Two fixes of a static pose from the same landmarks, the second's systematic
    covariance 0.81 of the first's and its value 2 mm further. Scaled down with the
    covariance (b' = 0.9 b, fully correlated: the old read-through) the difference of the
    fixes measures the error itself and the estimate lands beyond the second fix (a gain
    above one); with the common part it lands between the two."""
    B = np.diag([1e-4, 1e-4, 1e-5])
    w = 0.01 * B
    P = np.diag([1.0, 1.0, 1.0, 1e-6, 1e-6, 1e-6]).tolist()
    z1, z2 = np.array([0.010, 0.010, 0.003]), np.array([0.012, 0.012, 0.0036])
    first = consider_update(P, np.zeros((6, 3)).tolist(), z1.tolist(), w.tolist(), B.tolist())
    assert first is not None
    dX, P1, C1, _ = first
    y = (z2 - np.array(dX[:3])).tolist()
    landed = {}
    for name, C in (
        ("scaled", (0.9 * np.array(C1)).tolist()),
        ("common", carry_bias(C1, B.tolist(), (0.81 * B).tolist(), 1.0, 0.0, 0.0)),
    ):
        found = consider_update(P1, C, y, w.tolist(), (0.81 * B).tolist())
        assert found is not None
        landed[name] = np.array(dX[:3]) + np.array(found[0][:3])
    assert np.all(landed["scaled"] > z2 + 0.5 * (z2 - z1))  # far beyond the new fix
    assert np.all(landed["common"] >= z1) and np.all(landed["common"] <= z2 + 1e-9)


def test_the_carried_correlation_moves_with_the_body_as_moved_bias_says() -> None:
    rng = np.random.default_rng(3)
    C = rng.normal(0.0, 1e-3, (6, 3))
    A = rng.normal(0.0, 0.01, (3, 3))
    R_old = A @ A.T + 1e-6 * np.eye(3)
    T = moved_bias(0.4, -0.7)
    big = 10.0 * T @ R_old @ T.T  # holds the correlation: only the rigid carry applies
    got = np.array(carry_bias(C.tolist(), R_old.tolist(), big.tolist(), 0.8, 0.4, -0.7))
    np.testing.assert_allclose(got, 0.8 * C @ T.T, rtol=1e-12)
    # a smaller one, 0.2 of the carried covariance: its common part, 0.2 of the correlation
    R_new = 0.2 * T @ R_old @ T.T
    got = np.array(carry_bias(C.tolist(), R_old.tolist(), R_new.tolist(), 1.0, 0.4, -0.7))
    np.testing.assert_allclose(got, 0.2 * C @ T.T, rtol=1e-9, atol=1e-15)


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


def _drive(
    cfg: FilterConfig, k_b: float, seconds_straight: float, seconds_turning: float, seed: int = 7
) -> float:
    """Straight at 1 m/s, then turning in place at 1 rad/s, 1 % noise on each wheel per
    50 Hz sample, the true wheel base k_b W; a fix of the true pose every 1/30 s. The
    filter's wheel-base factor at the end."""
    rng = np.random.default_rng(seed)
    f = PoseFilter(0.0, 0.0, 0.0, np.diag([1e-4, 1e-4, 1e-5]), wheel_base=W, config=cfg)
    R = np.diag([0.002**2, 0.002**2, math.radians(0.2) ** 2])
    x = y = th = 0.0
    t_fix, n_straight = 0.0, round(seconds_straight * 50)
    for k in range(n_straight + round(seconds_turning * 50)):
        v_true = (1.0, 1.0) if k < n_straight else (-0.5 * k_b * W, 0.5 * k_b * W)
        vl, vr = (vt + rng.normal(0.0, 0.01) for vt in v_true)
        th += (v_true[1] - v_true[0]) * 0.02 / (k_b * W)
        x += 0.5 * (v_true[0] + v_true[1]) * 0.02 * math.cos(th)
        y += 0.5 * (v_true[0] + v_true[1]) * 0.02 * math.sin(th)
        f.predict(float(vl), float(vr), 0.02)
        t = (k + 1) * 0.02
        if t >= t_fix + 1 / 30:
            t_fix = t
            f.update_fix(_fix(x, y, math.atan2(math.sin(th), math.cos(th)), R, (1, 2)))
    return f.calibration.wheel_base_scale


def test_driving_straight_the_wheel_base_is_not_learnt_from_the_wheels_noise() -> None:
    """20 s straight with exact wheels: without the attenuation k_b is pushed up by the
    measured turn's noise (by 2.3 %); shrunk by the step's own measured turn (w^2 = r^2)
    by about a quarter of that (0.6 %); with the prior from the turn rates before, not at
    all (the rates measured are within their noise, w^2 = 0)."""
    drift = {}
    for name, cfg in (
        ("none", FilterConfig(attenuate_turn_scale=False, adapt_noise=False)),
        ("own", FilterConfig(turn_power_time_constant_s=0.0, adapt_noise=False)),
        ("prior", FilterConfig(adapt_noise=False)),
    ):
        drift[name] = _drive(cfg, 1.0, 20.0, 0.0) - 1.0
    assert drift["none"] > 0.015
    assert 0.1 * drift["none"] < drift["own"] < 0.4 * drift["none"]
    assert abs(drift["prior"]) < 0.02 * drift["none"]


def test_turning_in_place_the_wheel_base_is_still_learnt() -> None:
    """After 5 s straight, 6 s turning in place at 1 rad/s on a wheel base 2 % short: the
    attenuation keeps the turn's column (k_b within 0.05 % of the unattenuated filter's)
    and k_b is learnt most of the way from 1 to 0.98."""
    k_b = _drive(FilterConfig(adapt_noise=False), 0.98, 5.0, 6.0, seed=1)
    plain = _drive(FilterConfig(attenuate_turn_scale=False, adapt_noise=False), 0.98, 5.0, 6.0,
                   seed=1)  # fmt: skip
    assert abs(k_b - plain) < 0.0005
    assert abs(k_b - 0.98) < 0.005


def test_the_carry_is_the_common_part_in_the_carried_errors_basis() -> None:
    """Against the definition on numpy (eigh in the basis where the carried covariance is
    the identity) for a new covariance larger, smaller and mixed: the float paths agree."""
    rng = np.random.default_rng(5)
    C = rng.normal(0.0, 1e-3, (6, 3))
    A = rng.normal(0.0, 0.01, (3, 3))
    R_old = A @ A.T + 1e-5 * np.eye(3)
    T = moved_bias(0.3, 0.2)
    R_c = T @ R_old @ T.T
    L = np.linalg.cholesky(R_c)
    L_inv = np.linalg.inv(L)
    for lam in ((1.5, 2.0, 3.0), (0.2, 0.5, 0.9), (0.4, 1.0, 2.5)):
        Q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        R_new = L @ Q @ np.diag(lam) @ Q.T @ L.T
        want = 0.7 * C @ T.T @ L_inv.T @ Q @ np.diag(np.minimum(lam, 1.0)) @ Q.T @ L.T
        got = carry_bias(C.tolist(), R_old.tolist(), R_new.tolist(), 0.7, 0.3, 0.2)
        np.testing.assert_allclose(np.array(got), want, rtol=1e-8, atol=1e-14)
