"""Several robots under one ceiling share its LEDs: a robot that identifies darkens one
landmark at a time, so the robots that track keep their fixes, and each identifies right."""

from __future__ import annotations

import math

import numpy as np

from localizer.camera import T_body_camera_upward
from localizer.landmark_map import LandmarkMap
from localizer.localizer import Localizer
from localizer.robot import RobotGeometry
from sim.cameras import wide_angle_camera
from tests.localizer.drive import FleetRobot, drive_fleet

ROBOT = RobotGeometry(wheel_base=0.36, max_speed=1.0)
# A regular 6 x 4 grid, 1.2 m apart, at 2.5 m: identical neighbourhoods everywhere (a
# misidentified landmark would give a fix one grid step off).
GRID = LandmarkMap(
    np.arange(100, 124),
    np.array([[1.2 * (k % 6), 1.2 * (k // 6), 2.5] for k in range(24)]),
)


def _robot(traj: object) -> FleetRobot:
    cam = wide_angle_camera("pinhole", T_body_camera=T_body_camera_upward())
    return FleetRobot(Localizer(cam, GRID, ROBOT), cam, traj)  # type: ignore[arg-type]


def test_robots_identify_in_turn_without_stopping_each_other() -> None:
    robots = {
        # straight on at 0.3 m/s; parked; a circle of 0.4 m radius at 0.2 m/s
        "a": _robot(lambda t: (1.0 + 0.3 * t * math.cos(0.2), 1.3 + 0.3 * t * math.sin(0.2), 0.2)),
        "b": _robot(lambda t: (4.4, 2.5, 2.0)),
        "c": _robot(
            lambda t: (2.3 + 0.4 * math.sin(0.5 * t), 2.6 + 0.4 * (1 - math.cos(0.5 * t)), 0.5 * t)
        ),
    }
    drive_fleet(robots, GRID, duration_s=8.0, wheel_base=0.36, seed=4)
    for name, r in robots.items():
        err = r.run.errors_m()
        modes = r.run.modes()
        first = next(i for i, m in enumerate(modes) if m == "landmark")
        assert r.run.times_ns[first] < 4e9, name
        # Never a wrong fix, and once localized the robot keeps landmark fixes although the
        # others go on darkening landmarks to identify themselves.
        assert np.nanmax(err[first:]) < 0.02, name
        assert modes[first:].count("landmark") > 0.9 * len(modes[first:]), name
        # Only darken probes and "all lit": nobody darkened the whole ceiling.
        assert all(q.all_lit for q in r.run.requests), name


def test_sliding_robots_get_lost_but_never_take_a_wrong_fix() -> None:
    # Both move sideways, which wheel odometry cannot see (slip): their fixes disagree with
    # the odometry. "a" slides slowly and straight: the honest odometry noise lets the filter
    # follow it by its fixes. "c" slides while turning: it gets lost (position widened to 1 m
    # on a regular grid, where a shifted hypothesis fits the spots as well) and must find
    # itself again by LEDs. Neither ever takes a wrong fix.
    robots = {
        "a": _robot(lambda t: (1.0 + 0.3 * t, 1.3, 0.2)),
        "b": _robot(lambda t: (4.4, 2.5, 2.0)),
        "c": _robot(lambda t: (2.3 + 0.4 * math.sin(0.5 * t), 3.0, -1.0 + 0.5 * t)),
    }
    drive_fleet(robots, GRID, duration_s=8.0, wheel_base=0.36, seed=4)
    assert "lost" in robots["c"].run.modes()
    for name in ("a", "c"):
        run = robots[name].run
        err = run.errors_m()
        fixes = [e for e, m in zip(err, run.modes(), strict=True) if m == "landmark"]
        assert len(fixes) > 30 and max(fixes) < 0.05, name
