from __future__ import annotations

import math

import numpy as np
import pytest

from localizer.events import OdometryMeasured
from localizer.geometry import wrap_angle
from sim.robot import FloorBump, FramePose, OdometryModel, SimRobot, floor_height
from sim.routes import Drive, Goto, Route, TurnTo, Wait, heading_sweep


def _robot(route: Route, *, scale=(1.0, 1.0), noise=0.0, drop=0.0, bumps=(), start=(0.0, 0.0, 0.0)):
    return SimRobot(
        "r1", start=start, route=route,
        odometry=OdometryModel(100.0, scale, 0.4, noise), camera_rate_hz=30.0,
        frame_drop=drop, bumps=bumps, rng=np.random.default_rng(0),
    )  # fmt: skip


def test_constant_command_follows_the_closed_form_circle() -> None:
    v, w, x0, y0, th0 = 0.5, 0.7, 1.0, -2.0, 2.5
    robot = _robot(Route((Drive(100.0, v, w),)), start=(x0, y0, th0))
    items = robot.advance_to(3_000_000_000)
    # The first tick computes the command; the arc runs from t = 10 ms.
    frames = [i for i in items if isinstance(i, FramePose)]
    for f in frames[1:]:
        t = f.t_ns * 1e-9 - 0.01
        expected = (
            x0 + v / w * (math.sin(th0 + w * t) - math.sin(th0)),
            y0 - v / w * (math.cos(th0 + w * t) - math.cos(th0)),
        )
        np.testing.assert_allclose(f.T_world_body[:2, 3], expected, atol=1e-12)
        heading = math.atan2(f.T_world_body[1, 0], f.T_world_body[0, 0])
        assert wrap_angle(heading - th0 - w * t) == pytest.approx(0.0, abs=1e-12)
    assert len(frames) == 91  # t = 0 .. 3 s inclusive


def test_odometry_reports_scaled_wheel_speeds_and_zero_when_parked() -> None:
    robot = _robot(Route((Drive(1.0, 0.4, 0.5), Wait(1.0))), scale=(1.01, 0.98))
    odo = [i for i in robot.advance_to(1_900_000_000) if isinstance(i, OdometryMeasured)]
    assert len(odo) == 190
    vl, vr = 0.4 - 0.5 * 0.2, 0.4 + 0.5 * 0.2  # true wheel base 0.4 m
    np.testing.assert_allclose([odo[50].v_left, odo[50].v_right], [vl * 1.01, vr * 0.98])
    assert odo[0].v_left == 0.0  # before the first command
    assert odo[-1].v_left == 0.0 and odo[-1].v_right == 0.0


def test_goto_turn_and_sweep_reach_their_targets() -> None:
    steps = (Goto(1.0, 1.0, 0.5), TurnTo(-2.0), *heading_sweep(-2.0, math.radians(90), 0.2))
    robot = _robot(Route(steps))
    robot.advance_to(25_000_000_000)
    assert robot.follower.finished
    np.testing.assert_allclose([robot.x, robot.y], [1.0, 1.0], atol=0.012)
    assert wrap_angle(robot.theta + 2.0) == pytest.approx(0.0, abs=0.004)


def test_dropped_frames_leave_gaps() -> None:
    robot = _robot(Route(()), drop=0.3)
    frames = [i for i in robot.advance_to(10_000_000_000) if isinstance(i, FramePose)]
    assert 170 < len(frames) < 250  # 300 * 0.7 = 210
    gaps = np.diff([f.t_ns for f in frames])
    assert gaps.min() == 33_333_333 and gaps.max() >= 2 * 33_333_333


def test_floor_bump_lifts_and_tilts_the_body() -> None:
    bump = FloorBump(1.0, 0.0, 0.5, 0.03)
    h, gx, gy = floor_height((bump,), 1.0, 0.0)
    assert (h, gx, gy) == (0.03, 0.0, 0.0)
    h, gx, gy = floor_height((bump,), 0.75, 0.0)
    assert h == pytest.approx(0.015) and gx == pytest.approx(0.03 * 0.5 * math.pi / 0.5)
    robot = _robot(Route(()), bumps=(bump,))
    T = robot.T_world_body(0.75, 0.0, 0.0)  # driving along +x, uphill
    assert T[2, 3] == pytest.approx(0.015)
    # nose up: the body x axis points upward
    assert T[2, 0] == pytest.approx(math.sin(math.atan(gx)))
    np.testing.assert_allclose(T[:3, :3] @ T[:3, :3].T, np.eye(3), atol=1e-12)


def test_a_route_follower_tells_the_waypoints_still_ahead() -> None:
    from sim.routes import Goto, Route, RouteFollower, Wait

    route = Route((Goto(1.0, 0.0, 0.5), Wait(2.0), Goto(1.0, 1.0, 0.5), Goto(0.0, 1.0, 0.5)),
                  loop=True)  # fmt: skip
    f = RouteFollower(route)
    assert f.upcoming(3) == ((1.0, 0.0), (1.0, 1.0), (0.0, 1.0))
    assert f.upcoming(5) == ((1.0, 0.0), (1.0, 1.0), (0.0, 1.0))  # one lap, not repeated
    t, pose = 0.0, (0.0, 0.0, 0.0)
    while f.upcoming(1) == ((1.0, 0.0),) and t < 10.0:  # drive to the first point
        v, w = f.command(t, *pose)
        pose = (pose[0] + v * 0.01 * math.cos(pose[2]), pose[1] + v * 0.01 * math.sin(pose[2]),
                pose[2] + w * 0.01)  # fmt: skip
        t += 0.01
    assert f.upcoming(4) == ((1.0, 1.0), (0.0, 1.0), (1.0, 0.0))  # the loop comes round
    assert RouteFollower(Route(())).upcoming() == ()
