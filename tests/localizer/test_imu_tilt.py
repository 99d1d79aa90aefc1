"""The body's tilt from an IMU's gravity direction, and a pair fix on a tilted body."""

from __future__ import annotations

import math

import numpy as np
import pytest

from localizer.camera import predict_pixels
from localizer.imu_tilt import GRAVITY_M_S2, GravityTilt, ImuTiltConfig, tilt_from_gravity
from localizer.pose import solve_pose
from sim.cameras import wide_angle_camera

NS = 1_000_000_000


def _force(roll: float, pitch: float) -> tuple[float, float, float]:
    g = GRAVITY_M_S2
    return (-math.sin(pitch) * g, math.sin(roll) * math.cos(pitch) * g,
            math.cos(roll) * math.cos(pitch) * g)  # fmt: skip


@pytest.mark.parametrize(("roll", "pitch"), [(0.0, 0.0), (0.03, -0.02), (-0.035, 0.035)])
def test_tilt_from_gravity_inverts_the_specific_force(roll: float, pitch: float) -> None:
    assert tilt_from_gravity(*_force(roll, pitch)) == pytest.approx((roll, pitch), abs=1e-12)


def test_the_bodys_own_acceleration_is_taken_out() -> None:
    tilt = GravityTilt(ImuTiltConfig())
    rng = np.random.default_rng(0)
    roll, pitch = 0.01, 0.03
    for k in range(100):  # 1 s at 100 Hz: accelerating at 0.5 m/s^2 in a 0.4 rad/s turn
        t = k / 100
        v, w = 0.5 * t, 0.4
        f = np.array(_force(roll, pitch)) + np.array([0.5, v * w, 0.0]) + rng.normal(0, 0.02, 3)
        speed = v * (1 + rng.normal(0, 0.01))  # 1 % odometry noise
        tilt.sample(int(t * NS), (float(f[0]), float(f[1]), float(f[2])), speed, w)
    assert tilt.at(int(0.99 * NS)) == pytest.approx((roll, pitch), abs=0.004)
    assert tilt.at(int(1.5 * NS)) is None  # too old


def test_a_pair_fix_on_the_imus_tilt_is_not_moved_by_the_bump() -> None:
    cam = wide_angle_camera("pinhole")
    P = np.array([[1.0, 0.7, 2.5], [1.0, 1.3, 2.5]])
    pose, roll, pitch = (1.1, 1.0, 0.2), 0.0, math.radians(2.0)
    c, s = math.cos(pose[2]), math.sin(pose[2])
    Rz = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    cp, sp = math.cos(pitch), math.sin(pitch)
    Ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    T = np.eye(4)
    T[:3, :3] = Rz @ Ry
    T[:3, 3] = [pose[0], pose[1], 0.0]
    px, ok = predict_pixels(cam, T, P)
    assert ok.all()
    level = solve_pose(cam, px, P, initial=pose, pixel_sigma_px=0.3)
    s2 = 0.005**2
    tilted = solve_pose(cam, px, P, initial=pose, pixel_sigma_px=0.3,
                        floor_prior=((roll, pitch, 0.0), np.diag([s2, s2, 0.02**2])))  # fmt: skip
    assert level is not None and tilted is not None
    assert math.hypot(level.x - pose[0], level.y - pose[1]) > 0.05  # the bump read as motion
    assert math.hypot(tilted.x - pose[0], tilted.y - pose[1]) < 0.005
