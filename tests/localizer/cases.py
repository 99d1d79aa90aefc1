"""Reproductions of issue 12's buildings for localizer tests: lenses, calibration error,
ceilings, motions with turns in place, odometry at 50 Hz beside a 30 Hz camera, LEDs that
can or cannot be switched, and a kidnapped robot.

A `Case` is driven in closed loop by `run_case`: frames rendered through the *true* camera
(`sim.render.render_frame`), odometry as encoders report it (each wheel's mean speed over the
last sample interval, a scale error and white noise), the localizer given the *nominal*
(calibrated) camera and a surveyed map. Nothing here is tuned to the localizer: the numbers
are those the issue measured on an independent simulator.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from localizer.camera import CameraModel, T_body_camera_upward
from localizer.config import LocalizerConfig
from localizer.events import (
    FrameObserved,
    LedRequest,
    NoPose,
    OdometryMeasured,
    PoseEstimate,
)
from localizer.geometry import T_world_body_from_pose, wrap_angle
from localizer.landmark_map import LandmarkMap
from localizer.localizer import Localizer
from localizer.robot import RobotGeometry
from localizer.types import FloatArray, Pose
from sim.cameras import wide_angle_camera
from sim.render import render_frame
from tests.localizer.drive import leds_after

Segment = tuple[float, float, float]  # (seconds, v m/s, omega rad/s)


# -- cameras -----------------------------------------------------------------------------------
def strong_radtan_camera(T_body_camera: FloatArray | None = None) -> CameraModel:
    """A wide-angle radial-tangential lens as Zhang's method calibrates it (issue 12, case 2):
    fu ~300 px at 640x480, k1 -0.28, k2 0.07, small tangential terms."""
    T = T_body_camera_upward() if T_body_camera is None else T_body_camera
    return CameraModel(
        640, 480, 301.5, 300.8, 321.3, 238.1, "radial-tangential",
        np.array([-0.28, 0.07, 0.0008, -0.0005, 0.0]), T, 30.0,
    )  # fmt: skip


def fisheye_camera(T_body_camera: FloatArray | None = None) -> CameraModel:
    return wide_angle_camera("fisheye", T_body_camera=T_body_camera)


def miscalibrated(
    true: CameraModel,
    rng: np.random.Generator,
    *,
    focal_rel: float = 0.002,
    principal_px: float = 0.6,
    distortion_rel: float = 0.05,
) -> CameraModel:
    """The calibration handed to the localizer: the true camera off by up to these errors
    (each drawn uniformly within +-bound: focal +-0.2 %, centre +-0.6 px, each distortion
    coefficient +-5 % of itself)."""

    def u(b: float) -> float:
        return float(rng.uniform(-b, b))

    d = true.distortion * (1.0 + rng.uniform(-distortion_rel, distortion_rel, len(true.distortion)))
    return dataclasses.replace(
        true,
        fu=true.fu * (1 + u(focal_rel)),
        fv=true.fv * (1 + u(focal_rel)),
        cu=true.cu + u(principal_px),
        cv=true.cv + u(principal_px),
        distortion=d,
    )


# -- ceilings ----------------------------------------------------------------------------------
def grid_positions(nx: int, ny: int, spacing: float, z: float = 2.5) -> FloatArray:
    xs, ys = np.meshgrid(np.arange(nx) * spacing, np.arange(ny) * spacing)
    return np.column_stack([xs.ravel(), ys.ravel(), np.full(nx * ny, z)])


def irregular_positions(rng: np.random.Generator, n: int, extent: tuple[float, float],
                        spacing: float = 1.0, z: float = 2.5, z_jitter: float = 0.12
                        ) -> FloatArray:  # fmt: skip
    """Landmarks about `spacing` apart (jittered grid), heights +-`z_jitter`."""
    nx, ny = int(extent[0] / spacing) + 1, int(extent[1] / spacing) + 1
    p = grid_positions(nx, ny, spacing, z)
    p[:, :2] += rng.uniform(-0.3 * spacing, 0.3 * spacing, (len(p), 2))
    p[:, 2] += rng.uniform(-z_jitter, z_jitter, len(p))
    return p[:n] if n else p


def pair_positions(centres: Sequence[tuple[float, float, float]], gap: float = 0.6,
                   z: float = 2.5, z_jitter: float = 0.0, rng: np.random.Generator | None = None
                   ) -> FloatArray:  # fmt: skip
    """Landmark pairs `gap` apart at (x, y, angle) centres (sparse pairs with gaps between)."""
    out = []
    for x, y, a in centres:
        for s in (-0.5, 0.5):
            out.append([x + s * gap * math.cos(a), y + s * gap * math.sin(a), z])
    p = np.array(out)
    if z_jitter and rng is not None:
        p[:, 2] += rng.uniform(-z_jitter, z_jitter, len(p))
    return p


# -- motion ------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Path:
    """A body path sampled every `dt` s: time, pose and signed distance travelled."""

    t: FloatArray
    pose: FloatArray  # (N, 3), heading unwrapped
    s: FloatArray

    @classmethod
    def from_segments(cls, start: Pose, segments: Sequence[Segment], dt: float = 5e-4) -> Path:
        """Integrate (seconds, v, omega) commands (switching instantly) from `start`."""
        x, y, th = start
        ts, poses, ss = [0.0], [(x, y, th)], [0.0]
        t = s = 0.0
        for dur, v, w in segments:
            for _ in range(max(round(dur / dt), 1)):
                if abs(w) > 1e-12:
                    r = v / w
                    x += r * (math.sin(th + w * dt) - math.sin(th))
                    y -= r * (math.cos(th + w * dt) - math.cos(th))
                else:
                    x += v * dt * math.cos(th)
                    y += v * dt * math.sin(th)
                th += w * dt
                t += dt
                s += v * dt
                ts.append(t)
                poses.append((x, y, th))
                ss.append(s)
        return cls(np.array(ts), np.array(poses), np.array(ss))

    @property
    def duration(self) -> float:
        return float(self.t[-1])

    def at(self, t: float) -> tuple[float, float, float, float]:
        """(x, y, theta unwrapped, s) at time t (linear interpolation)."""
        t = min(max(t, 0.0), self.duration)
        x, y, th = (float(np.interp(t, self.t, self.pose[:, k])) for k in range(3))
        return x, y, th, float(np.interp(t, self.t, self.s))


def drive_then_turn(start: Pose, *, v: float = 1.0, drive_s: float = 2.0, omega: float = 3.0,
                    turn_s: float = 2.0, repeats: int = 2) -> list[Segment]:  # fmt: skip
    """Straight at `v`, stop, turn in place at `omega` (no pause between), repeated."""
    segs: list[Segment] = [(0.5, 0.0, 0.0)]
    for k in range(repeats):
        segs += [(drive_s, v, 0.0), (turn_s, 0.0, omega * (1 if k % 2 == 0 else -1))]
    return segs


def heading_sweep(step_deg: float = 10.0, steps: int = 36, dwell_s: float = 0.5,
                  omega: float = 0.5) -> list[Segment]:  # fmt: skip
    """Turn on the spot in steps, parking after each (the paper's test bed, Sec. V)."""
    segs: list[Segment] = [(1.0, 0.0, 0.0)]
    for _ in range(steps):
        segs += [(math.radians(step_deg) / omega, 0.0, omega), (dwell_s, 0.0, 0.0)]
    return segs


# -- a case and its run ------------------------------------------------------------------------
@dataclass
class Case:
    """A building, a robot and what happens to it.

    Attributes:
        true_camera: renders the frames; camera: what the localizer is told (calibration).
        truth: true landmark positions (N, 3); surveyed: the map given to the localizer.
        leds_controllable: the LEDs follow the localizer's requests (else: all lit, always,
            and the localizer starts from `prior`).
        kidnap: (time s, dx, dy, dtheta): the robot is carried by this rigid motion at that
            time (odometry sees nothing).
        prior: the pose handed over by `set_initial_pose` (None: none).
    """

    name: str
    true_camera: CameraModel
    camera: CameraModel
    truth: FloatArray
    surveyed: FloatArray
    path: Path
    wheel_base: float = 0.36
    max_speed: float = 1.5
    odom_rate_hz: float = 50.0
    odom_noise_m_s: float = 0.01
    wheel_scale: tuple[float, float] = (1.005, 0.996)
    frame_rate_hz: float = 30.0
    leds_controllable: bool = True
    kidnap: tuple[float, float, float, float] | None = None
    prior: Pose | None = None
    seed: int = 0
    config: LocalizerConfig | None = None


@dataclass
class CaseRun:
    times_s: list[float] = field(default_factory=list)
    truth: list[Pose] = field(default_factory=list)
    outputs: list[PoseEstimate | NoPose] = field(default_factory=list)

    def errors_m(self) -> FloatArray:
        return np.array([
            math.hypot(o.x - p[0], o.y - p[1]) if isinstance(o, PoseEstimate) else math.nan
            for o, p in zip(self.outputs, self.truth, strict=True)
        ])  # fmt: skip

    def heading_errors_rad(self) -> FloatArray:
        return np.array([
            abs(float(wrap_angle(o.theta - p[2]))) if isinstance(o, PoseEstimate) else math.nan
            for o, p in zip(self.outputs, self.truth, strict=True)
        ])  # fmt: skip

    def modes(self) -> list[str]:
        return [o.mode for o in self.outputs]

    def landmark_fraction(self, since_s: float = 0.0) -> float:
        m = [o.mode for o, t in zip(self.outputs, self.times_s, strict=True) if t >= since_s]
        return m.count("landmark") / max(len(m), 1)

    def misidentified(self, bound_m: float = 0.10) -> int:
        """Frames in `landmark` mode whose pose is farther than `bound_m` from the truth
        (a fix from wrongly paired spots; honest fixes are within centimetres)."""
        err = self.errors_m()
        return sum(
            1
            for o, e in zip(self.outputs, err, strict=True)
            if o.mode == "landmark" and e > bound_m
        )

    def summary(self) -> str:
        err = self.errors_m()
        ok = err[np.isfinite(err)]
        h = np.degrees(self.heading_errors_rad())
        h = h[np.isfinite(h)]
        modes = self.modes()
        frac = {m: modes.count(m) / len(modes) for m in ("landmark", "dead_reckoning", "lost",
                                                          "identifying")}  # fmt: skip
        p95 = float(np.percentile(ok, 95)) * 100 if len(ok) else math.nan
        mx = float(np.max(ok)) * 100 if len(ok) else math.nan
        return (
            f"p95 {p95:6.2f} cm  max {mx:7.2f} cm  heading {np.mean(h) if len(h) else 0:.3f}"
            f" deg  landmark {frac['landmark']:.0%} dr {frac['dead_reckoning']:.0%} lost "
            f"{frac['lost']:.0%} id {frac['identifying']:.0%}  misid {self.misidentified()}"
        )


def run_case(case: Case) -> CaseRun:
    """Drive `case` in closed loop; one output per frame."""
    rng = np.random.default_rng(case.seed)
    ids = list(range(1, len(case.truth) + 1))
    lmap = LandmarkMap(np.array(ids), case.surveyed)
    robot = RobotGeometry(wheel_base=case.wheel_base, max_speed=case.max_speed)
    loc = Localizer(case.camera, lmap, robot, case.config)
    if case.prior is not None:
        loc.set_initial_pose(*case.prior, 0)
    lit = set(ids)
    odom_dt = 1.0 / case.odom_rate_hz
    frame_dt = 1.0 / case.frame_rate_hz
    events = [(k * odom_dt, 0) for k in range(1, int(case.path.duration / odom_dt) + 1)]
    events += [(0.013 + k * frame_dt, 1)
               for k in range(int((case.path.duration - 0.013) / frame_dt) + 1)]  # fmt: skip
    events.sort()
    W = case.wheel_base
    run = CaseRun()
    pending: LedRequest | None = None
    last = case.path.at(0.0)
    for t, kind in events:
        t_ns = round(t * 1e9)
        outs: list[object] = []
        if pending is not None and case.leds_controllable:
            lit, changed = leds_after(pending, ids, t_ns)
            outs += loc.handle(changed)
            pending = None
        if kind == 0:
            now = case.path.at(t)
            v = (now[3] - last[3]) / odom_dt
            w = (now[2] - last[2]) / odom_dt
            last = now
            vl = (v - w * W / 2) * case.wheel_scale[0] + rng.normal(0, case.odom_noise_m_s)
            vr = (v + w * W / 2) * case.wheel_scale[1] + rng.normal(0, case.odom_noise_m_s)
            outs += loc.handle(OdometryMeasured(t_ns, vl, vr))
        else:
            pose = _true_pose(case, t)
            rows = [i - 1 for i in sorted(lit)]
            image = render_frame(
                case.true_camera, T_world_body_from_pose(*pose), case.truth[rows],
                np.ones(len(rows)), rng=rng,
            )  # fmt: skip
            frame_outs = loc.handle(FrameObserved(t_ns, image))
            outs += frame_outs
            est = [o for o in frame_outs if isinstance(o, PoseEstimate | NoPose)]
            run.times_s.append(t)
            run.truth.append(pose)
            run.outputs.append(est[0])
        for o in outs:
            if isinstance(o, LedRequest):
                pending = o
    return run


def _true_pose(case: Case, t: float) -> Pose:
    x, y, th, _ = case.path.at(t)
    if case.kidnap is not None and t >= case.kidnap[0]:
        _, dx, dy, dth = case.kidnap
        x0, y0, _, _ = case.path.at(case.kidnap[0])
        c, s = math.cos(dth), math.sin(dth)
        x, y = x0 + dx + c * (x - x0) - s * (y - y0), y0 + dy + s * (x - x0) + c * (y - y0)
        th += dth
    return x, y, float(wrap_angle(th))


def surveyed(truth: FloatArray, rng: np.random.Generator, sigma_m: float = 0.003) -> FloatArray:
    return truth + rng.normal(0.0, sigma_m, truth.shape)
