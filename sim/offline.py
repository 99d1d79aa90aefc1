"""Simulate one robot of a scenario offline into a recording sink, with its ground truth.

The sink is anything with the writer's four `add_*` methods (`RecordingSink`; `add_imu` and
`set_start_pose` too when the robot has an IMU or states its start pose): `sim` does not
import `recording`; `irloc.simulated_recording` hands it a `recording.RecordingWriter`.

The recording starts as a live start-up would (Sec. III-A): all LEDs dark, then one landmark
at a time lit, nearest the robot first, for a few frames each, until two have been seen; then
every LED. The robot stands still during this sweep and sets off once all LEDs are lit.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Iterable, Mapping, Sequence
from contextlib import AbstractContextManager
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from localizer.camera import CameraModel, predict_pixels
from localizer.events import LedsChanged, OdometryMeasured
from localizer.geometry import T_world_body_from_pose
from localizer.robot import RobotGeometry
from localizer.types import ImageU8
from sim.build import RobotRig, build_robot, build_world, seed_generators
from sim.cameras import Lens
from sim.imu import SimImu
from sim.robot import FramePose
from sim.scenario import Scenario
from sim.virtual_site import render_view
from sim.world import World

NS = 1_000_000_000


class RecordingSink(Protocol):
    """Where a simulated drive goes: `recording.RecordingWriter` is one."""

    def add_frame(self, t_ns: int, image: ImageU8, /) -> object: ...
    def add_odometry(self, t_ns: int, v_left: float, v_right: float, /) -> None: ...
    def add_leds(self, event: LedsChanged, /) -> None: ...
    def add_groundtruth(self, t_ns: int, x: float, y: float, theta: float, /) -> None: ...


# Opens the sink of one recording from what its header holds: the camera handed over (the
# nominal calibration), the robot's geometry and the surveyed landmark records.
OpenSink = Callable[
    [CameraModel, RobotGeometry, Iterable[Mapping[str, object]]],
    AbstractContextManager[RecordingSink],
]


@dataclass(frozen=True)
class SweepConfig:
    """The identification sweep at the start of a recording.

    Attributes:
        frames_per_landmark: camera frames each landmark stays lit alone.
        radio_latency_s: from one landmark's LED change to the next one's command.
        settle_s: time with every LED lit before the robot drives off.
        max_candidates: landmarks tried at most.
        min_brightness: a lit landmark dimmer than this (relative) counts as not seen.
    """

    frames_per_landmark: int = 3
    radio_latency_s: float = 0.03
    settle_s: float = 0.5
    max_candidates: int = 12
    min_brightness: float = 0.1


@dataclass(frozen=True)
class SimulationSummary:
    """What `simulate_recording` wrote."""

    frames: int
    odometry: int
    led_changes: int
    sweep_end_ns: int
    kidnaps: tuple[tuple[int, int], ...] = ()  # (picked up, put down) times, ns


def visible_landmarks(world: World, rig: RobotRig, pose: tuple[float, float, float]) -> set[int]:
    """Landmarks whose lit LED the robot's true camera would see from a planar pose."""
    T = T_world_body_from_pose(*pose)
    ids = list(world.landmarks)
    p = np.array([world.landmarks[i].p_true for i in ids])
    _, valid = predict_pixels(rig.camera_true, T, p)
    return {i for i, ok in zip(ids, valid, strict=True) if ok}


def sweep_schedule(
    world: World, rig: RobotRig, config: SweepConfig, t_start_ns: int
) -> tuple[list[LedsChanged], int]:
    """The LED changes of the identification sweep and the time the robot may drive off.

    Landmarks are tried nearest the robot's start first (by the surveyed map), skipping those
    the radio cannot reach (a live run gets no acknowledgement from them).
    """
    x, y, _ = rig.spec.start
    visible = visible_landmarks(world, rig, rig.spec.start)
    reachable = [lm for lm in world.landmarks.values() if lm.reachable]
    reachable.sort(key=lambda lm: float(np.hypot(lm.p_surveyed[0] - x, lm.p_surveyed[1] - y)))
    period_ns = round(NS / rig.camera_true.rate_hz)
    per_ns = config.frames_per_landmark * period_ns + round(config.radio_latency_s * NS)
    per_ns = -(-per_ns // 1_000_000) * 1_000_000  # whole milliseconds: readable leds.csv
    events = [LedsChanged(t_start_ns)]
    t, seen = t_start_ns + round(config.radio_latency_s * NS), 0
    for lm in reachable[: config.max_candidates]:
        events.append(LedsChanged(t, frozenset({lm.id})))
        t += per_ns
        if lm.id in visible and lm.battery.led_brightness() >= config.min_brightness:
            seen += 1
            if seen >= 2:
                break
    events.append(LedsChanged(t, all_lit=True))
    return events, t + round(config.settle_s * NS)


def simulate_recording(
    scenario: Scenario,
    open_sink: OpenSink,
    *,
    seed: int | None = None,
    duration_s: float | None = None,
    lens: Lens | None = None,
    robot: str | None = None,
    sweep: SweepConfig | None = None,
    led_program: Callable[[int], Sequence[LedsChanged]] | None = None,
    progress: Callable[[float], None] | None = None,
) -> SimulationSummary:
    """Simulate one robot of a scenario into a recording sink, ground truth included.

    Args:
        scenario: the site.
        open_sink: opens the sink (`irloc.simulated_recording` writes a recording folder).
        seed: overrides the scenario's seed.
        duration_s: recording length from the start of the sweep (default: the scenario's).
        lens: overrides every camera's lens.
        robot: which robot (default: the first).
        sweep: the identification sweep.
        led_program: LED changes to play once the sweep is over, given the time the robot
            drives off (e.g. the survey's blink schedule, `survey.blinks`); in time order.
        progress: called with the simulated seconds done, now and then.

    Raises:
        ValueError: unknown robot name.
    """
    sc, world, rig, gens = recording_site(scenario, seed=seed, lens=lens, robot=robot)
    end_ns = round((sc.duration_s if duration_s is None else duration_s) * NS)

    leds, drive_ns = sweep_schedule(world, rig, sweep or SweepConfig(), 0)
    if led_program is not None:
        leds += [c for c in led_program(drive_ns) if c.t_ns > leds[-1].t_ns]
    rig.robot.paused_until_ns = drive_ns
    frames = odometry = 0
    spec = rig.spec
    # the IMU and the start pose draw from streams of their own: the rest of the
    # recording is the same with or without them
    extra = np.random.SeedSequence(scenario.seed if seed is None else seed).spawn(6)
    imu = SimImu(spec.imu, np.random.default_rng(extra[4])) if spec.imu is not None else None
    with open_sink(rig.camera_nominal, rig.geometry, world.landmark_records()) as w:
        if spec.start_pose_radius_m is not None:
            _write_start_pose(w, spec.start, spec.start_pose_radius_m, extra[5])
        pending = list(leds)
        t_ns = 0
        # with an IMU, one control tick at a time: its sample reads the robot's state then
        chunk_ns = rig.robot.tick_ns if imu is not None else NS // 10
        while t_ns < end_ns:
            t_ns = min(t_ns + chunk_ns, end_ns)
            for item in rig.robot.advance_to(t_ns):
                while pending and pending[0].t_ns <= item.t_ns:
                    change = pending.pop(0)
                    world.set_lit(None if change.all_lit else set(change.lit))
                    w.add_leds(change)
                if isinstance(item, OdometryMeasured):
                    if spec.odometry_recorded:
                        w.add_odometry(item.t_ns, item.v_left, item.v_right)
                        odometry += 1
                    if imu is not None:
                        _write_imu(w, imu, rig, item.t_ns)
                elif isinstance(item, FramePose):  # (a lift's arrival: one floor recorded)
                    _write_frame(w, world, rig, item, gens[2], sc)
                    frames += 1
            if progress is not None:
                progress(t_ns / NS)
    kidnaps = tuple(rig.robot.kidnaps)
    return SimulationSummary(frames, odometry, len(leds) - len(pending), drive_ns, kidnaps)


def recording_site(
    scenario: Scenario,
    *,
    seed: int | None = None,
    lens: Lens | None = None,
    robot: str | None = None,
) -> tuple[Scenario, World, RobotRig, list[np.random.Generator]]:
    """The site `simulate_recording` builds for one robot: (the one-robot scenario, the
    world, the robot, the generators of world, radio, renderer and robot). Called again with
    the same arguments it rebuilds the same truth (a benchmark's reference).

    Raises:
        ValueError: unknown robot name.
    """
    sc = scenario.with_lens(lens) if lens else scenario
    names = [r.name for r in sc.robots]
    name = robot or names[0]
    if name not in names:
        raise ValueError(f"unknown robot {name!r}; the scenario has {names}")
    sc = dataclasses.replace(sc, robots=tuple(r for r in sc.robots if r.name == name))
    gens = seed_generators(sc.seed if seed is None else seed, 4)
    world = build_world(sc, gens[0])
    rig = build_robot(sc.robots[0], sc, gens[3], index=0)
    return sc, world, rig, gens


def _write_imu(writer: RecordingSink, imu: SimImu, rig: RobotRig, t_ns: int) -> None:
    """The IMU sample of the tick just driven (`simulate_recording` drives one tick at a
    time then, so the robot's state is that tick's)."""
    robot = rig.robot
    pose = (robot.x, robot.y, robot.theta)
    sample = imu.sample(t_ns, pose, robot.T_world_body(*pose, lift_m=robot.lift_m))
    add = getattr(writer, "add_imu", None)
    if sample is not None and add is not None:
        add(sample.t_ns, sample.gyro, sample.accel)


def _write_start_pose(
    writer: RecordingSink,
    start: tuple[float, float, float],
    radius_m: float,
    seed: np.random.SeedSequence,
) -> None:
    """start_pose.yaml: the true start as the robot would know it, off by a draw from the
    prior it states (position sigma radius / 2.45, heading 2 deg)."""
    rng = np.random.default_rng(seed)
    sigma = radius_m / 2.4477
    dx, dy = rng.normal(0.0, sigma, 2)
    dth = float(rng.normal(0.0, math.radians(2.0)))
    put = getattr(writer, "set_start_pose", None)
    if put is not None:
        put(start[0] + float(dx), start[1] + float(dy), start[2] + dth, radius_m)


def _write_frame(
    writer: RecordingSink,
    world: World,
    rig: RobotRig,
    item: FramePose,
    rng: np.random.Generator,
    scenario: Scenario,
) -> None:
    world.advance(item.t_ns)
    image = render_view(world, rig.camera_true, item.T_world_body, rng, scenario.render)
    writer.add_frame(item.t_ns, image)
    writer.add_groundtruth(item.t_ns, *item.pose)
