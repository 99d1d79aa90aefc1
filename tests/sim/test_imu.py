"""The simulated IMU, a robot without recorded odometry, a stated start pose, and the
controller's turn-rate limit: numbers against the simulator's truth."""

from __future__ import annotations

import itertools
import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from irloc.simulate_cli import main
from localizer.geometry import rotation_z
from recording.reader import read_groundtruth, read_recording
from sim.imu import GRAVITY_M_S2, ImuSpec, SimImu
from sim.routes import DriveLimits, Route, RouteFollower, TurnTo


def test_gyro_is_the_heading_rate_and_gravity_tilts_with_the_body() -> None:
    imu = SimImu(ImuSpec(gyro_noise_rad_s=0.0, gyro_bias_rad_s=0.0, accel_noise_m_s2=0.0),
                 np.random.default_rng(0))  # fmt: skip
    level = np.eye(4)
    assert imu.sample(0, (0.0, 0.0, 0.0), level) is None  # no interval yet
    # 10 ms along an arc: 1 m/s, 0.5 rad/s
    s = imu.sample(10_000_000, (0.01, 0.000025, 0.005), level)
    assert s is not None
    assert s.gyro[2] == pytest.approx(0.5, rel=1e-6)
    # a 2 deg pitch (nose up): gravity leans back along the body's x
    pitch = math.radians(2.0)
    T = np.eye(4)
    T[:3, :3] = rotation_z(0.005) @ np.array(
        [[math.cos(pitch), 0, -math.sin(pitch)], [0, 1, 0], [math.sin(pitch), 0, math.cos(pitch)]]
    )
    s = imu.sample(20_000_000, (0.02, 0.0001, 0.01), T)
    assert s is not None
    assert s.accel[2] == pytest.approx(GRAVITY_M_S2 * math.cos(pitch), abs=1e-3)
    assert abs(s.accel[0]) == pytest.approx(GRAVITY_M_S2 * math.sin(pitch), abs=0.01)


def test_turn_rate_limit_ramps_the_turn() -> None:
    limits = DriveLimits(max_omega_radps=2.5, angular_accel_radps2=10.0)
    follower = RouteFollower(Route((TurnTo(math.pi / 2),), False), limits, tick_s=0.01)
    rates = [follower.command(0.01 * k, 0.0, 0.0, 0.0)[1] for k in range(30)]
    assert rates[0] == pytest.approx(0.1)  # 10 rad/s^2 x 10 ms
    assert rates[24] == pytest.approx(2.5)
    assert all(b - a <= 0.1 + 1e-12 for a, b in itertools.pairwise(rates))


def test_recording_without_odometry_with_imu_and_start_pose(tmp_path: Path) -> None:
    scenario = yaml.safe_load(Path("sim/scenarios/paper_testbed.yaml").read_text())
    robot = scenario["robots"][0]
    robot["odometry"]["recorded"] = False
    robot["imu"] = {"gyro_noise_rad_s": 0.001, "gyro_bias_rad_s": 0.0}
    robot["start_pose"] = {"radius_m": 0.2}
    robot["route"]["steps"] = [{"wait": 0.5}, {"turn_to_deg": 60}, {"wait": 1}]
    path = tmp_path / "scenario.yaml"
    path.write_text(yaml.safe_dump(scenario))
    out = tmp_path / "rec"
    assert main([str(path), str(out), "--duration", "2.5", "--quiet"]) == 0
    rec = read_recording(out)
    assert len(rec.odom_t_ns) == 0
    assert rec.start_pose is not None and rec.start_pose.radius_m == 0.2
    assert math.hypot(rec.start_pose.x - 0.6, rec.start_pose.y - 0.35) < 0.3
    assert len(rec.imu_t_ns) == 249  # 100 Hz ticks, the first has no interval
    _, gt = read_groundtruth(out)
    heading = np.unwrap(gt[:, 2])
    turned = float(np.sum(rec.imu[:, 2]) * 0.01)  # the gyro's integral
    assert turned == pytest.approx(heading[-1] - heading[0], abs=0.01)
    np.testing.assert_allclose(rec.imu[:, 5], GRAVITY_M_S2, atol=0.1)  # level floor
