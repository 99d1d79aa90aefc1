from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pytest

from localizer.calibrated_odometry import jacob_f, motion_model
from localizer.filter_config import FilterConfig
from localizer.geometry import wrap_angle
from localizer.odometry import integrate_arc
from localizer.pose import PoseFix
from localizer.pose_filter import PoseFilter

W = 0.36  # configured wheel base, metres
K_TRUE = (1.01, 1.0, 1.02)  # right wheel 1 % larger, wheel base 2 % longer than configured
DT = 0.02  # odometry at 50 Hz
FIX_SIGMA = (0.004, 0.004, math.radians(0.3))


@dataclass
class Drive:
    truth: np.ndarray  # (N + 1, 3) poses
    speeds: np.ndarray  # (N, 2) measured (v_left, v_right)


def patrol(
    loops: int, side_x: float = 6.0, side_y: float = 4.0
) -> list[tuple[float, float, float]]:
    """(v m/s, omega rad/s, duration s) segments: rectangles with turns on the spot and arcs."""
    seg: list[tuple[float, float, float]] = []
    for _ in range(loops):
        for side in (side_x, side_y, side_x, side_y):
            seg += [(0.5, 0.0, side / 0.5), (0.0, 0.5, (math.pi / 2) / 0.5)]
        seg += [(0.4, 0.3, 4.0), (0.4, -0.3, 4.0)]  # an S-bend
    return seg


def simulate(
    segments: list[tuple[float, float, float]],
    rng: np.random.Generator,
    start: tuple[float, float, float] = (0.0, 0.0, 0.0),
    noise_m_per_sqrt_s: float = FilterConfig().wheel_noise_m_per_sqrt_s,
) -> Drive:
    """Truth by exact arcs with the true wheel geometry; measured speeds with the errors."""
    k_r, k_l, k_b = K_TRUE
    W_true = k_b * W
    pose = start
    truth, speeds = [start], []
    for v, omega, duration in segments:
        for _ in range(round(duration / DT)):
            vr, vl = v + omega * W_true / 2, v - omega * W_true / 2
            pose = integrate_arc(*pose, vl, vr, DT, W_true)
            truth.append(pose)
            noise = rng.normal(0, noise_m_per_sqrt_s / math.sqrt(DT), 2)
            speeds.append((vl / k_l + noise[0], vr / k_r + noise[1]))
    return Drive(np.array(truth, dtype=float), np.array(speeds))


def noisy_fix(pose: np.ndarray, rng: np.random.Generator) -> PoseFix:
    z = pose + rng.normal(0, FIX_SIGMA)
    return PoseFix(z[0], z[1], float(wrap_angle(z[2])), np.diag(np.square(FIX_SIGMA)))


def near_a_landmark_pair(p: np.ndarray) -> bool:
    """Sparse landmark pairs: fixes only within 1 m of two corners of the patrol."""
    return bool(min(math.hypot(p[0] - cx, p[1] - cy) for cx, cy in [(0, 0), (6, 4)]) < 1.0)


def run(
    filt: PoseFilter, drive: Drive, rng: np.random.Generator, fixes: bool = True
) -> list[float]:
    """Feed the drive; fixes at 10 Hz near landmark pairs. Returns the NEES before each fix."""
    nees = []
    for i, (vl, vr) in enumerate(drive.speeds):
        filt.predict(vl, vr, DT)
        truth = drive.truth[i + 1]
        if fixes and i % 5 == 4 and near_a_landmark_pair(truth):
            e = truth - filt.state
            e[2] = wrap_angle(e[2])
            nees.append(float(e @ np.linalg.solve(filt.covariance, e)))
            filt.update_fix(noisy_fix(truth, rng))
    return nees


def dead_reckon(start: np.ndarray, speeds: np.ndarray, k: tuple[float, float, float]) -> np.ndarray:
    x, y, th = start
    for vl, vr in speeds:
        x, y, th = integrate_arc(x, y, th, k[1] * vl, k[0] * vr, DT, k[2] * W)
    return np.array([x, y, th])


@pytest.fixture(scope="module")
def learnt() -> tuple[PoseFilter, list[float]]:
    rng = np.random.default_rng(5)
    drive = simulate(patrol(3), rng)
    filt = PoseFilter(0.0, 0.0, 0.0, np.diag([1e-4, 1e-4, 1e-4]), wheel_base=W)
    nees = run(filt, drive, rng)
    return filt, nees


def test_calibration_converges_to_the_true_wheel_errors(
    learnt: tuple[PoseFilter, list[float]],
) -> None:
    cal = learnt[0].calibration
    print("calibration", cal)
    # wheel radii to 0.3 %; the wheel base (seen only in the turns) to 1 %, from 2 % off
    np.testing.assert_allclose([cal.right_scale, cal.left_scale], K_TRUE[:2], atol=0.003)
    assert cal.wheel_base_scale == pytest.approx(K_TRUE[2], abs=0.01)
    # and its reported uncertainty covers the error
    err = np.array([cal.right_scale, cal.left_scale, cal.wheel_base_scale]) - K_TRUE
    assert float(err @ np.linalg.solve(cal.covariance, err)) < 16.3  # chi2(3) 99.9 %


def test_calibrated_dead_reckoning_drifts_far_less_over_a_10_m_gap(
    learnt: tuple[PoseFilter, list[float]],
) -> None:
    filt, _ = learnt
    rng = np.random.default_rng(9)
    start = filt.state
    gap = simulate([(0.5, 0.0, 10.0), (0.0, 0.5, math.pi), (0.5, 0.0, 10.0)], rng, tuple(start))
    # the robot drives 10 m with a 90 deg turn in the middle, no landmark in sight
    run(filt, gap, rng, fixes=False)
    filtered = np.hypot(*(filt.state[:2] - gap.truth[-1, :2]))
    raw = dead_reckon(start, gap.speeds, (1.0, 1.0, 1.0))
    raw_err = np.hypot(*(raw[:2] - gap.truth[-1, :2]))
    assert raw_err > 0.2
    assert filtered < raw_err / 3
    # the filter's own uncertainty covers its error
    e = gap.truth[-1] - filt.state
    e[2] = wrap_angle(e[2])
    assert float(e @ np.linalg.solve(filt.covariance, e)) < 16.3


def test_nees_is_consistent(learnt: tuple[PoseFilter, list[float]]) -> None:
    nees = np.array(learnt[1])
    assert len(nees) > 200
    assert 3 / 2 < np.mean(nees) < 3 * 2  # 3 dof: mean 3, roughly
    assert np.mean(nees > 16.3) < 0.02


def test_fix_across_the_heading_cut_pulls_the_short_way() -> None:
    filt = PoseFilter(1.0, 2.0, math.pi - 0.01, np.diag([1e-2, 1e-2, 1e-2]), wheel_base=W)
    nis = filt.update_fix(PoseFix(1.0, 2.0, -math.pi + 0.01, np.diag([1e-2, 1e-2, 1e-2])))
    assert nis == pytest.approx(0.02**2 / 0.02, rel=1e-6)
    theta = filt.state[2]
    assert -math.pi < theta <= math.pi
    assert abs(wrap_angle(theta - math.pi)) < 1e-9  # halfway: exactly on the cut
    assert -math.pi < filt.output_state[2] <= math.pi


def test_predict_grows_the_covariance_whatever_the_rate() -> None:
    covs = []
    for rate_hz in (20, 200):
        filt = PoseFilter(0.0, 0.0, 0.0, np.zeros((3, 3)), wheel_base=W)
        for _ in range(2 * rate_hz):
            filt.predict(0.5, 0.5, 1.0 / rate_hz)
        covs.append(filt.covariance)
        np.testing.assert_allclose(filt.state, [1.0, 0.0, 0.0], atol=1e-12)
    assert np.all(np.diag(covs[0]) > 0)
    np.testing.assert_allclose(covs[0], covs[1], rtol=0.05, atol=1e-12)
    filt.predict(1.0, 1.0, 0.0)  # no time passes: nothing changes
    np.testing.assert_allclose(filt.state, [1.0, 0.0, 0.0], atol=1e-12)


def test_gate_rejects_an_inconsistent_fix() -> None:
    filt = PoseFilter(0.0, 0.0, 0.0, np.diag([1e-4, 1e-4, 1e-4]), wheel_base=W)
    far = PoseFix(0.5, 0.0, 0.0, np.diag([1e-4, 1e-4, 1e-4]))
    assert filt.nis(far) == pytest.approx(0.25 / 2e-4)
    assert filt.update_fix(far, max_nis=16.27) == pytest.approx(0.25 / 2e-4)
    np.testing.assert_array_equal(filt.state, [0.0, 0.0, 0.0])
    filt.update_fix(far)
    assert filt.state[0] == pytest.approx(0.25)


def test_output_follows_a_correction_without_a_jump() -> None:
    filt = PoseFilter(0.0, 0.0, 0.0, np.diag([0.01, 0.01, 1e-4]), wheel_base=W)
    for _ in range(50):  # past output_settle_s (1 s) after the reset, parked
        filt.predict(0.0, 0.0, 0.02)
    filt.update_fix(PoseFix(0.1, 0.0, 0.0, np.diag([1e-8, 1e-8, 1e-8])))
    assert filt.state[0] == pytest.approx(0.1, abs=1e-5)
    assert filt.output_state[0] == pytest.approx(0.0, abs=1e-12)  # no jump
    for _ in range(5):
        filt.predict(0.0, 0.0, 0.02)
    halfway = filt.output_state[0]
    tau = filt.config.output_time_constant_s
    assert halfway == pytest.approx(0.1 * (1.0 - math.exp(-0.1 / tau)), abs=1e-3)  # after 0.1 s
    assert 0.0 < halfway < 0.099
    for _ in range(100):
        filt.predict(0.0, 0.0, 0.02)
    assert filt.output_state[0] == pytest.approx(0.1, abs=1e-4)
    # a relocalisation (beyond output_snap_m) is not smoothed
    filt.update_fix(PoseFix(5.0, 0.0, 0.0, np.diag([1e-8, 1e-8, 1e-8])))
    np.testing.assert_allclose(filt.output_state, filt.state)


def test_output_takes_corrections_at_once_while_settling() -> None:
    filt = PoseFilter(0.0, 0.0, 0.0, np.diag([0.01, 0.01, 1e-4]), wheel_base=W)
    for _ in range(45):  # 0.9 s after the reset: still settling (output_settle_s = 1 s)
        filt.predict(0.0, 0.0, 0.02)
    filt.update_fix(PoseFix(0.1, 0.0, 0.0, np.diag([1e-8, 1e-8, 1e-8])))
    np.testing.assert_allclose(filt.output_state, filt.state)
    filt.reset(1.0, 0.0, 0.0, np.diag([0.01, 0.01, 1e-4]))  # a reset settles again
    filt.update_fix(PoseFix(1.1, 0.0, 0.0, np.diag([1e-8, 1e-8, 1e-8])))
    assert filt.output_state[0] == pytest.approx(1.1, abs=1e-5)


def test_reset_keeps_the_calibration() -> None:
    filt = PoseFilter(0.0, 0.0, 0.0, np.eye(3) * 1e-4, wheel_base=W)
    filt._X[3:] = (1.01, 0.99, 1.02)  # as if learnt
    filt.reset(3.0, 4.0, 3.5, np.eye(3) * 1e-2)
    np.testing.assert_allclose(filt.state, [3.0, 4.0, 3.5 - 2 * math.pi])
    np.testing.assert_allclose(filt.covariance, np.eye(3) * 1e-2)
    assert filt.calibration.right_scale == pytest.approx(1.01)
    assert filt.full_covariance[0, 3] == 0.0


def test_frozen_calibration_stays_at_one() -> None:
    rng = np.random.default_rng(2)
    drive = simulate(patrol(1), rng)
    filt = PoseFilter(0.0, 0.0, 0.0, np.eye(3) * 1e-4, wheel_base=W,
                      config=FilterConfig(estimate_calibration=False))  # fmt: skip
    run(filt, drive, rng)
    cal = filt.calibration
    assert (cal.right_scale, cal.left_scale, cal.wheel_base_scale) == (1.0, 1.0, 1.0)


def test_jacob_f_matches_finite_differences() -> None:
    X = [1.0, 2.0, 3.0, 1.01, 0.99, 1.02]
    u = (0.3, 0.5, 0.05, W)
    F_top, G = jacob_f(X, *u)
    F = np.vstack([F_top, np.hstack([np.zeros((3, 3)), np.eye(3)])])
    eps = 1e-7

    def f(X: np.ndarray) -> np.ndarray:
        return np.array(motion_model(list(X), *u))

    num = np.column_stack([(f(X + eps * e) - f(X - eps * e)) / (2 * eps) for e in np.eye(6)])
    np.testing.assert_allclose(F, num, atol=1e-8)
    # G: derivative with respect to the true (calibrated) wheel speeds
    vl, vr, Wt = 0.3 * 0.99, 0.5 * 1.01, W * 1.02

    def g(a: float, b: float) -> np.ndarray:
        return np.array(motion_model([1.0, 2.0, 3.0, 1.0, 1.0, 1.0], a, b, 0.05, Wt))[:3]

    numG = np.column_stack(
        [
            (g(vl + eps, vr) - g(vl - eps, vr)) / (2 * eps),
            (g(vl, vr + eps) - g(vl, vr - eps)) / (2 * eps),
        ]
    )
    np.testing.assert_allclose(G, numG, atol=1e-8)


def test_deferred_covariance_equals_step_by_step_propagation() -> None:
    """P = F P F^T + G M G^T at every step, written out with numpy, against the filter."""
    cfg = FilterConfig(calibration_walk_per_sqrt_s=0.0, attenuate_turn_scale=False)
    filt = PoseFilter(1.0, 2.0, 3.0, np.diag([1e-3, 2e-3, 1e-3]), wheel_base=W, config=cfg)
    X = filt.full_state.tolist()
    P = filt.full_covariance
    rng = np.random.default_rng(4)
    for vl, vr in rng.uniform(-0.5, 0.8, (40, 2)):
        dt = 0.01
        F_top, G = jacob_f(X, vl, vr, dt, W)
        F = np.vstack([F_top, np.hstack([np.zeros((3, 3)), np.eye(3)])])
        m = [
            (
                cfg.wheel_noise_m_per_sqrt_s**2 * dt
                + cfg.wheel_slip_m_per_sqrt_m**2 * abs(k * v * dt)
            )
            / dt**2
            for k, v in ((X[4], vl), (X[3], vr))
        ]
        Gf = np.vstack([G, np.zeros((3, 2))])
        P = F @ P @ F.T + Gf @ np.diag(m) @ Gf.T
        X = motion_model(X, vl, vr, dt, W)
        filt.predict(vl, vr, dt)
    np.testing.assert_allclose(filt.full_state, X, atol=1e-12)
    np.testing.assert_allclose(filt.full_covariance, P, rtol=1e-9, atol=1e-15)


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("wheel_noise_m_per_sqrt_s", -1.0),
        ("calibration_prior_sigma", 0.0),
        ("output_snap_m", math.nan),
    ],
)
def test_config_errors_name_the_field(field: str, value: float) -> None:
    with pytest.raises(ValueError, match=field):
        FilterConfig(**{field: value})


def test_bad_reset_input_raises() -> None:
    with pytest.raises(ValueError, match="covariance"):
        PoseFilter(0.0, 0.0, 0.0, np.eye(2), wheel_base=W)
    with pytest.raises(ValueError, match="wheel_base"):
        PoseFilter(0.0, 0.0, 0.0, np.eye(3), wheel_base=0.0)


def test_a_copy_carries_the_deferred_propagation_and_leaves_the_original_alone() -> None:
    """A frame's copy is not flushed: it applies the original's pending odometry steps with
    its own in one go, and gives the covariance the original would have after the same
    steps; the original does not see the copy's steps."""
    f = PoseFilter(1.0, 2.0, 0.3, np.diag([0.01, 0.02, 0.003]), wheel_base=0.4)
    for vl, vr in ((0.5, 0.6), (0.4, 0.7), (0.6, 0.6)):
        f.predict(vl, vr, 0.02)
    twin = f.copy()
    twin.predict(0.5, 0.8, 0.013)
    ref = PoseFilter(1.0, 2.0, 0.3, np.diag([0.01, 0.02, 0.003]), wheel_base=0.4)
    for vl, vr in ((0.5, 0.6), (0.4, 0.7), (0.6, 0.6)):
        ref.predict(vl, vr, 0.02)
        ref.covariance  # noqa: B018 (flushed after every step)
    before = ref.covariance
    ref.predict(0.5, 0.8, 0.013)
    # (batched and stepwise propagation agree to rounding, as in test_propagation)
    np.testing.assert_allclose(twin.covariance, ref.covariance, rtol=1e-9, atol=1e-16)
    np.testing.assert_allclose(twin.pose, ref.pose, atol=1e-15)
    np.testing.assert_allclose(f.covariance, before, rtol=1e-9, atol=1e-16)
    assert not np.allclose(f.covariance, twin.covariance)
