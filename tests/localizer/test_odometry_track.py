"""The localizer's raw dead-reckoning track: trapezoid intervals, history, pose lookup."""

from __future__ import annotations

import math

import numpy as np
import pytest

from localizer.odometry import integrate_arc
from localizer.odometry_track import OdometryTrack

W = 0.36  # wheel base, metres
MS = 1_000_000  # nanoseconds per millisecond


def test_a_sample_is_the_mean_speed_over_the_interval_before_it() -> None:
    track = OdometryTrack(W, history_s=1.0)
    assert track.add_sample(0, 0.2, 0.3) == (0.2, 0.3, 0.0)
    vl, vr, dt = track.add_sample(20 * MS, 0.4, 0.5)
    assert (vl, vr) == (0.4, 0.5) and dt == pytest.approx(0.02)
    expected = integrate_arc(0.0, 0.0, 0.0, 0.4, 0.5, 0.02, W)
    np.testing.assert_allclose(track.pose, expected, rtol=0, atol=1e-15)


def test_a_frame_marked_before_the_next_sample_is_corrected_by_it() -> None:
    # Driving straight, then turning in place from 20 ms on: a frame at 30 ms was placed at
    # the old speeds; the sample at 40 ms says the wheels turned the whole interval.
    track = OdometryTrack(W, history_s=1.0)
    track.add_sample(0, 0.5, 0.5)
    track.add_sample(20 * MS, 0.5, 0.5)
    track.step(30 * MS, *track.speeds)
    track.mark(30 * MS)
    assert track.pose_at(30 * MS) == pytest.approx((0.015, 0.0, 0.0))
    track.add_sample(40 * MS, -0.54, 0.54)  # 3 rad/s
    x, y, th = track.pose_at(30 * MS)
    assert (x, y) == pytest.approx((0.01, 0.0), abs=1e-12)
    assert th == pytest.approx(3.0 * 0.01)
    assert track.pose[2] == pytest.approx(3.0 * 0.02)


def test_samples_are_integrated_with_the_mean_of_their_ends() -> None:
    track = OdometryTrack(W, history_s=1.0, interval_mean=False)
    assert track.add_sample(0, 0.2, 0.3) == (0.2, 0.3, 0.0)  # the first only sets the time
    vl, vr, dt = track.add_sample(20 * MS, 0.4, 0.5)
    assert (vl, vr) == pytest.approx((0.3, 0.4)) and dt == pytest.approx(0.02)
    expected = integrate_arc(0.0, 0.0, 0.0, 0.3, 0.4, 0.02, W)
    np.testing.assert_allclose(track.pose, expected, rtol=0, atol=1e-15)
    assert track.speeds == (0.4, 0.5) and track.t_sample_ns == 20 * MS


def test_step_to_a_frame_uses_the_last_speeds_and_never_goes_back() -> None:
    track = OdometryTrack(W, history_s=1.0)
    track.add_sample(0, 0.5, 0.5)
    assert track.step(10 * MS, *track.speeds) == pytest.approx(0.01)
    np.testing.assert_allclose(track.pose, (0.005, 0.0, 0.0), atol=1e-15)
    assert track.step(5 * MS, 0.5, 0.5) == 0.0  # earlier than the state: nothing
    assert track.t_state_ns == 10 * MS


def test_pose_at_returns_the_latest_remembered_pose_at_or_before() -> None:
    track = OdometryTrack(W, history_s=1.0)
    for k in range(5):  # turning on the spot: the heading tells the samples apart
        track.add_sample(k * 100 * MS, -0.18, 0.18)
    heading = [track.pose_at(k * 100 * MS)[2] for k in range(5)]
    np.testing.assert_allclose(heading, [0.0, 0.1, 0.2, 0.3, 0.4], atol=1e-12)
    assert track.pose_at(150 * MS)[2] == pytest.approx(0.1)
    assert track.pose_at(-1)[2] == 0.0  # before them all: the earliest
    track.step(450 * MS, *track.speeds)
    track.mark(450 * MS)
    assert track.pose_at(460 * MS)[2] == pytest.approx(0.45)


def test_history_keeps_only_its_horizon() -> None:
    track = OdometryTrack(W, history_s=0.5)
    for k in range(101):  # 2 s at 50 Hz, straight at 0.5 m/s
        track.add_sample(k * 20 * MS, 0.5, 0.5)
    # 0.5 s back (and one sample before it) is still there; 1 s back is gone: the earliest
    assert track.pose_at(1500 * MS)[0] == pytest.approx(0.75)
    assert track.pose_at(1000 * MS)[0] == pytest.approx(track.pose_at(0)[0])
    assert track.pose_at(1000 * MS)[0] > 0.7
    assert math.isclose(track.pose[0], 1.0)
