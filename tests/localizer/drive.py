"""A small closed-loop driver for localizer tests: a robot on a trajectory under a ceiling of
landmarks, frames rendered by `sim.render.render_frame`, wheel odometry, and LEDs that obey the
localizer's `LedRequest`s (as a live site would)."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from localizer.camera import CameraModel
from localizer.events import (
    FrameObserved,
    LedRequest,
    LedsChanged,
    NoPose,
    OdometryMeasured,
    PoseEstimate,
)
from localizer.geometry import T_world_body_from_pose, wrap_angle
from localizer.landmark_map import LandmarkMap
from localizer.localizer import Localizer
from localizer.types import Pose
from sim.render import ExtendedSource, render_frame


@dataclass
class Run:
    """What a drive produced: per frame the true pose and the localizer's output."""

    times_ns: list[int] = field(default_factory=list)
    truth: list[Pose] = field(default_factory=list)
    outputs: list[PoseEstimate | NoPose] = field(default_factory=list)
    requests: list[LedRequest] = field(default_factory=list)

    def errors_m(self) -> np.ndarray:
        """Position error per frame with a pose (NaN where none), metres."""
        return np.array(
            [
                np.hypot(o.x - t[0], o.y - t[1]) if isinstance(o, PoseEstimate) else np.nan
                for o, t in zip(self.outputs, self.truth, strict=True)
            ]
        )

    def heading_errors_rad(self) -> np.ndarray:
        return np.array(
            [
                abs(float(wrap_angle(o.theta - t[2]))) if isinstance(o, PoseEstimate) else np.nan
                for o, t in zip(self.outputs, self.truth, strict=True)
            ]
        )

    def modes(self) -> list[str]:
        return [o.mode for o in self.outputs]


def wheel_speeds(
    trajectory: Callable[[float], Pose], t: float, wheel_base: float, interval_s: float = 0.0
) -> tuple[float, float]:
    """(v_left, v_right) of a differential drive following `trajectory`, m/s: the mean over
    the `interval_s` before `t` (as encoders report, docs/recording.md), or at `t` when 0
    (central differences)."""
    if interval_s > 0:
        a, b = trajectory(max(t - interval_s, 0.0)), trajectory(t)
        dt = t - max(t - interval_s, 0.0)
        if dt <= 0:
            return wheel_speeds(trajectory, t, wheel_base)
        w = float(wrap_angle(b[2] - a[2])) / dt
        chord = float(np.hypot(b[0] - a[0], b[1] - a[1]))
        mid = a[2] + 0.5 * float(wrap_angle(b[2] - a[2]))
        sign = 1.0 if np.cos(mid) * (b[0] - a[0]) + np.sin(mid) * (b[1] - a[1]) >= 0 else -1.0
        half = 0.5 * abs(w) * dt
        arc = chord * half / np.sin(half) if half > 1e-9 else chord  # arc length of the chord
        v = sign * arc / dt
        return v - w * wheel_base / 2, v + w * wheel_base / 2
    h = 1e-4
    a, b = trajectory(max(t - h, 0.0)), trajectory(t + h)
    dt = t + h - max(t - h, 0.0)
    v = (np.cos(a[2]) * (b[0] - a[0]) + np.sin(a[2]) * (b[1] - a[1])) / dt
    w = float(wrap_angle(b[2] - a[2])) / dt
    return v - w * wheel_base / 2, v + w * wheel_base / 2


def leds_after(request: LedRequest, ids: Sequence[int], t_ns: int) -> tuple[set[int], LedsChanged]:
    """The lit set after the owner applied `request`, and the `LedsChanged` that says so."""
    lit = set(ids) - set(request.dark) if request.all_lit else set(request.lit)
    all_lit = lit == set(ids)
    return lit, LedsChanged(t_ns, frozenset() if all_lit else frozenset(lit), all_lit)


def drive(
    loc: Localizer,
    camera: CameraModel,
    landmark_map: LandmarkMap,
    trajectory: Callable[[float], Pose],
    *,
    duration_s: float,
    wheel_base: float,
    seed: int = 0,
    frame_rate_hz: float = 30.0,
    odom_rate_hz: float = 100.0,
    dead_ids: Sequence[int] = (),
    strays_world: np.ndarray | None = None,
    extended: Sequence[ExtendedSource] = (),
    odom_scale: tuple[float, float] = (1.0, 1.0),
    true_camera: CameraModel | None = None,
    odometry: bool = True,
) -> Run:
    """Drive the localizer in closed loop and collect its per-frame outputs.

    The wheel speeds come from finite differences of the trajectory; `odom_scale` multiplies
    the measured left/right speeds (an odometry bias). LEDs follow the localizer's requests one
    event later; `dead_ids` never light. `strays_world` are always-on unmapped sources.
    `odometry=False`: no odometry at all (the localizer's motion model carries it).
    """
    rng = np.random.default_rng(seed)
    cam_true = true_camera or camera
    ids = landmark_map.ids.tolist()
    lit: set[int] = set(ids)
    run = Run()
    events: list[tuple[int, int]] = []
    frame_dt = int(1e9 / frame_rate_hz)
    odom_dt = int(1e9 / odom_rate_hz)
    t_end = int(duration_s * 1e9)
    events += [(t, 0) for t in range(0, t_end + 1, odom_dt)] if odometry else []
    events += [(t, 1) for t in range(frame_dt // 2, t_end + 1, frame_dt)]
    events.sort()
    pending: LedRequest | None = None
    strays = np.zeros((0, 3)) if strays_world is None else np.asarray(strays_world)
    for t_ns, kind in events:
        t = t_ns * 1e-9
        outs: list[object] = []
        if pending is not None:
            lit, changed = leds_after(pending, ids, t_ns)
            outs += loc.handle(changed)
            pending = None
        if kind == 0:
            vl, vr = wheel_speeds(trajectory, t, wheel_base, 1.0 / odom_rate_hz)
            outs += loc.handle(OdometryMeasured(t_ns, vl * odom_scale[0], vr * odom_scale[1]))
        else:
            pose = trajectory(t)
            on = [i for i in ids if i in lit and i not in dead_ids]
            rows = [landmark_map.index_of(i) for i in on]
            sources = np.vstack([landmark_map.positions[rows].reshape(-1, 3), strays])
            image = render_frame(
                cam_true,
                T_world_body_from_pose(*pose),
                sources,
                np.ones(len(sources)),
                rng=rng,
                extended=extended,
            )
            frame_events = loc.handle(FrameObserved(t_ns, image))
            outs += frame_events
            frame_outs = [o for o in frame_events if isinstance(o, PoseEstimate | NoPose)]
            assert len(frame_outs) == 1
            run.times_ns.append(t_ns)
            run.truth.append(pose)
            run.outputs.append(frame_outs[0])
        for o in outs:
            if isinstance(o, LedRequest):
                run.requests.append(o)
                pending = o
    return run


@dataclass
class FleetRobot:
    """One robot of `drive_fleet`: its localizer, camera and true trajectory."""

    loc: Localizer
    camera: CameraModel
    trajectory: Callable[[float], Pose]
    run: Run = field(default_factory=Run)


def drive_fleet(
    robots: dict[str, FleetRobot],
    landmark_map: LandmarkMap,
    *,
    duration_s: float,
    wheel_base: float,
    seed: int = 0,
    dwell_s: float = 0.1,
) -> dict[str, FleetRobot]:
    """Drive several robots under one ceiling whose LEDs they share, as the server's LED
    coordinator does: requests are applied one at a time in arrival order (latest kept per
    robot), each state held at least `dwell_s`, and every robot sees every change."""
    rng = np.random.default_rng(seed)
    ids = landmark_map.ids.tolist()
    lit: set[int] = set(ids)
    queue: dict[str, LedRequest] = {}
    frame_dt, odom_dt = int(1e9 / 30), int(1e9 / 100)
    t_end = int(duration_s * 1e9)
    ticks = sorted([(t, 0) for t in range(0, t_end + 1, odom_dt)] +
                   [(t, 1) for t in range(frame_dt // 2, t_end + 1, frame_dt)])  # fmt: skip
    next_apply = 0
    for t_ns, kind in ticks:
        t = t_ns * 1e-9
        if queue and t_ns >= next_apply:
            name = next(iter(queue))
            req = queue.pop(name)
            lit, event = leds_after(req, ids, t_ns)
            next_apply = t_ns + int(dwell_s * 1e9)
            for rname, r in robots.items():
                _queue_requests(r.loc.handle(event), r, queue, rname)
        for name, r in robots.items():
            if kind == 0:
                vl, vr = wheel_speeds(r.trajectory, t, wheel_base, odom_dt * 1e-9)
                r.loc.handle(OdometryMeasured(t_ns, vl, vr))
                continue
            pose = r.trajectory(t)
            rows = [landmark_map.index_of(i) for i in ids if i in lit]
            sources = landmark_map.positions[rows].reshape(-1, 3)
            image = render_frame(
                r.camera, T_world_body_from_pose(*pose), sources, np.ones(len(sources)), rng=rng
            )
            outs = r.loc.handle(FrameObserved(t_ns, image))
            r.run.times_ns.append(t_ns)
            r.run.truth.append(pose)
            r.run.outputs.append(next(o for o in outs if isinstance(o, PoseEstimate | NoPose)))
            _queue_requests(outs, r, queue, name)
    return robots


def _queue_requests(
    outs: Sequence[object], robot: FleetRobot, queue: dict[str, LedRequest], name: str
) -> None:
    """Queue a robot's LED requests: its latest only, at the back of the queue."""
    for o in outs:
        if isinstance(o, LedRequest):
            robot.run.requests.append(o)
            queue.pop(name, None)
            queue[name] = o
