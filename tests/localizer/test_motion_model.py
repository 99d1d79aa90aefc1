"""The motion model without odometry: the speed and turn rate learnt from fixes (and a gyro),
the arc prediction with honest process noise, and closed loop without any odometry: the
LED sweep from rest (Sec. III-A), and tracking at speed with turns in place."""

from __future__ import annotations

import math
from collections.abc import Iterator

import numpy as np
import pytest

from localizer.config import LocalizerConfig
from localizer.events import ImuMeasured, PoseEstimate
from localizer.landmark_map import LandmarkMap
from localizer.localizer import Localizer
from localizer.motion_model import ConstantVelocity, MotionModelConfig
from localizer.odometry import integrate_arc
from localizer.pose_filter import PoseFilter
from localizer.robot import RobotGeometry
from sim.cameras import wide_angle_camera
from tests.localizer.cases import grid_positions
from tests.localizer.drive import drive

NS = 1_000_000_000


def _arc_fixes(
    v: float, w: float, seconds: float, sigma_m: float, sigma_rad: float, seed: int
) -> Iterator[tuple[int, float, float, float]]:
    rng = np.random.default_rng(seed)
    x = y = th = 0.0
    dt = 1 / 30
    for k in range(int(seconds * 30)):
        x, y, th = integrate_arc(x, y, th, v - 0.2 * w, v + 0.2 * w, dt, 0.4)
        yield (
            int((k + 1) * dt * NS),
            x + rng.normal(0, sigma_m), y + rng.normal(0, sigma_m), th + rng.normal(0, sigma_rad),
        )  # fmt: skip


@pytest.mark.parametrize(("v", "w"), [(1.2, 0.8), (-0.4, 0.0), (0.0, -2.5)])
def test_speed_and_turn_rate_are_learnt_from_fixes(v: float, w: float) -> None:
    model = ConstantVelocity(MotionModelConfig(), max_speed_m_s=2.0, max_turn_rad_s=4.0)
    for t, x, y, th in _arc_fixes(v, w, 1.5, 0.003, 0.001, seed=1):
        model.fixed(t, x, y, th, 0.003**2, 0.001**2)
    assert model.v == pytest.approx(v, abs=0.05)
    assert model.w == pytest.approx(w, abs=0.03)
    assert math.sqrt(model.var_v) < 0.1 and math.sqrt(model.var_w) < 0.1


def test_a_gyro_gives_the_turn_rate_and_fixes_then_give_the_speed_only() -> None:
    model = ConstantVelocity(MotionModelConfig(), max_speed_m_s=2.0, max_turn_rad_s=4.0)
    for t, x, y, th in _arc_fixes(1.0, 0.5, 1.0, 0.003, 0.001, seed=2):
        model.gyro(t - 1_000_000, 0.7)  # a biased gyro: its rate is what w follows
        model.fixed(t, x, y, th, 0.003**2, 0.001**2)
    assert model.has_gyro
    assert model.w == pytest.approx(0.7, abs=0.01)
    assert model.v == pytest.approx(1.0, abs=0.1)  # (0.13 m/s noise per fix pair)


def test_from_rest_the_bounds_grow_with_the_acceleration() -> None:
    cfg = MotionModelConfig(accel_sigma_m_s2=1.0, angular_accel_sigma_rad_s2=3.0)
    model = ConstantVelocity(cfg, max_speed_m_s=0.6, max_turn_rad_s=3.3)
    model.predict(0)
    assert model.speed_bounds(0) == (0.0, 0.0)
    assert model.speed_bounds(NS // 10) == pytest.approx((0.3, 0.9))
    assert model.speed_bounds(NS) == pytest.approx((0.6, 3.3))  # within the robot's limits
    moving = ConstantVelocity(
        MotionModelConfig(start_at_rest=False), max_speed_m_s=0.6, max_turn_rad_s=3.3
    )
    assert moving.speed_bounds(0) == pytest.approx((0.6, 3.3))


def test_predict_motion_follows_the_arc_and_adds_the_process_noise() -> None:
    f = PoseFilter(1.0, 2.0, 0.3, np.diag([1e-4, 1e-4, 1e-5]), wheel_base=0.4)
    k_before = f.full_covariance[3:, 3:].copy()
    f.predict_motion(1.5, 0.9, 0.1, 4e-4, 2e-4)
    expected = integrate_arc(1.0, 2.0, 0.3, 1.5 - 0.18, 1.5 + 0.18, 0.1, 0.4)
    np.testing.assert_allclose(f.state, expected, atol=1e-12)
    P = f.covariance
    dx_dth = -(expected[1] - 2.0)  # d(x, y)/d theta of the arc's chord
    assert P[0, 0] == pytest.approx(1e-4 + dx_dth**2 * 1e-5 + 4e-4, rel=1e-9)
    assert P[2, 2] == pytest.approx(1e-5 + 2e-4)
    np.testing.assert_array_equal(f.full_covariance[3:, 3:], k_before)


TRIANGLE = LandmarkMap(
    np.array([1, 2, 3]), np.array([[0.0, 0.0, 2.5], [1.2, 0.0, 2.5], [0.6, 1.0392, 2.45]])
)


def test_the_paper_sweep_from_rest_identifies_without_odometry() -> None:
    cam = wide_angle_camera("pinhole")
    robot = RobotGeometry(wheel_base=0.36, max_speed=0.6)
    cfg = LocalizerConfig()
    loc = Localizer(cam, TRIANGLE, robot, cfg.__class__(identification=type(
        cfg.identification)(probe="light_one")))  # fmt: skip
    pose = (0.6, 0.35, 0.4)
    run = drive(loc, cam, TRIANGLE, lambda t: pose, duration_s=1.5, wheel_base=0.36, seed=4,
                odometry=False)  # fmt: skip
    first = next(i for i, o in enumerate(run.outputs) if isinstance(o, PoseEstimate))
    assert run.times_ns[first] < 1.0e9
    err = run.errors_m()[first:]
    assert np.nanmax(err) < 0.005
    assert run.modes()[-1] == "landmark"


def _run_and_turn(t: float) -> tuple[float, float, float]:
    """Parked 0.4 s (the start pose is where it was parked), 3 m/s^2 to 1.8 m/s, on to
    x = 3.5, stopped at once and turned in place at up to 2.5 rad/s (ramped over 0.25 s),
    then on along the new heading at 1.8 m/s."""
    x0, y0, a, v = 0.8, 1.0, 3.0, 1.8
    t_acc = v / a  # 0.6 s
    run_s = t_acc + (3.5 - x0 - 0.5 * a * t_acc**2) / v
    if t < 0.4:
        return x0, y0, 0.0
    s = t - 0.4
    if s < t_acc:
        return x0 + 0.5 * a * s * s, y0, 0.0
    if s < run_s:
        return x0 + 0.5 * a * t_acc**2 + v * (s - t_acc), y0, 0.0
    s -= run_s
    turn = 2.5 * (s * s / 0.5 if s < 0.25 else s - 0.125)
    if s < 0.6:
        return 3.5, y0, turn
    heading = 2.5 * (0.6 - 0.125)
    d = v * (s - 0.6)
    return 3.5 + d * math.cos(heading), y0 + d * math.sin(heading), heading


def test_tracking_at_speed_with_a_turn_in_place_without_odometry() -> None:
    cam = wide_angle_camera("fisheye")
    grid = LandmarkMap(np.arange(100, 100 + 12 * 8), grid_positions(12, 8, 0.5))
    robot = RobotGeometry(wheel_base=0.45, max_speed=2.0)
    loc = Localizer(cam, grid, robot)
    loc.set_initial_pose(0.9, 1.1, 0.05, 0, radius_m=0.3)
    run = drive(loc, cam, grid, _run_and_turn, duration_s=3.4, wheel_base=0.45, seed=6,
                odometry=False)  # fmt: skip
    modes = run.modes()
    first = modes.index("landmark")
    assert run.times_ns[first] < 0.3e9
    assert modes[first:].count("landmark") >= 0.95 * len(modes[first:])
    err = run.errors_m()[first:]
    assert np.nanpercentile(err, 95) < 0.02
    assert np.nanmax(err) < 0.05  # never a neighbour's 50 cm


def test_a_gyro_sample_reaches_the_model() -> None:
    loc = Localizer(wide_angle_camera("pinhole"), TRIANGLE, RobotGeometry(0.36, 1.0))
    assert loc.handle(ImuMeasured(10, (0.0, 0.0, 0.4), (0.0, 0.0, 9.81))) == []
    assert loc._reckoning.motion.w == pytest.approx(0.4, abs=1e-3)
