"""The independent generator's clock and odometry faults (`bench/foreign/generate.py`)."""

from __future__ import annotations

import dataclasses

import numpy as np

from bench.foreign.cases import CASES
from bench.foreign.generate import Motion, drive, odometry_stamps, wheel_spin

BASE = CASES["clock_lag"]


def test_odometry_in_bursts_is_stamped_when_the_last_of_each_burst_is_taken() -> None:
    case = dataclasses.replace(BASE, odom_burst=3, odom_jitter_s=0.0)
    t = np.arange(1, 8) * 0.02  # samples taken every 20 ms
    ns = odometry_stamps(case, t, np.random.default_rng(0))
    ms = [v / 1e6 for v in ns]
    assert ms == [60.0, 61.0, 62.0, 120.0, 121.0, 122.0, 140.0]  # the last burst: one sample


def test_jittered_stamps_are_late_never_early_and_strictly_increasing() -> None:
    case = dataclasses.replace(BASE, odom_burst=1, odom_jitter_s=0.004)
    t = np.arange(1, 200) * 0.02
    ns = np.array(odometry_stamps(case, t, np.random.default_rng(1)))
    late = ns * 1e-9 - t
    assert late.min() >= 0 and late.max() <= 0.004 + 1e-9 and late.std() > 0.0008
    assert np.all(np.diff(ns) > 0)


def test_wheels_spin_only_inside_a_wet_patch() -> None:
    case = dataclasses.replace(BASE, slip_zones=((1.0, -1.0, 2.0, 1.0, 1.12, 1.06),))
    x = np.array([0.5, 1.5, 2.5])
    pose = np.column_stack([x, np.zeros(3), np.zeros(3)])
    spin = wheel_spin(case, Motion(np.arange(3.0), pose, np.ones((3, 2))))
    np.testing.assert_array_equal(spin, [[1.0, 1.0], [1.12, 1.06], [1.0, 1.0]])


def test_a_stalled_robot_stays_put_while_its_wheels_turn() -> None:
    case = dataclasses.replace(
        CASES["stuck_wheels"], segments=((5.0, 0.8, 0.0),), drive_lag_s=0.0, stall_s=(0.2, 0.4)
    )
    m = drive(case, 0.6, start_s=0.0)
    k0, k1 = 200, 399  # 1 kHz samples inside the stall
    np.testing.assert_allclose(m.pose[k1], m.pose[k0])
    np.testing.assert_allclose(m.wheels[k0:k1], 0.8)  # the wheels report the command
    assert m.pose[599, 0] - m.pose[k1, 0] > 0.15  # moving again after it
