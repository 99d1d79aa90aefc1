"""A simulated differential-drive robot: true motion, wheel odometry, floor bumps and the
times its upward camera takes frames.

Motion: the controller sets (v, omega) at every control tick (the odometry rate); between
ticks the wheels turn at constant speed, so the body follows an exact circular arc
(`localizer.odometry.integrate_arc` with the *true* wheel base). Odometry: each sample at tick
t_k reports the wheel speeds averaged over (t_{k-1}, t_k], as counted by encoders that assume
the nominal wheel radius (so unequal true radii scale each wheel's speed), plus noise
proportional to the wheel speed (a parked robot reads exactly zero). Floor bumps and a tilted
floor lift and tilt the body (and so the camera) without changing the planar pose. On a
slippery patch the wheels turn as commanded (and the encoders count that) but the body moves
only by (1 - slip) of it. A kidnap carries the robot, wheels still, to another pose.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from localizer.events import OdometryMeasured
from localizer.geometry import rotation_z, wrap_angle
from localizer.odometry import integrate_arc
from localizer.types import FloatArray
from sim.routes import DriveLimits, Lift, Route, RouteFollower


@dataclass(frozen=True)
class FloorBump:
    """A smooth hump (or dip, for negative height) in the floor: raised cosine of `radius_m`."""

    x: float
    y: float
    radius_m: float
    height_m: float


@dataclass(frozen=True)
class FloorTilt:
    """The whole floor out of level: a plane through (x, y) at height 0 rising by `slope_rad`
    towards the heading `direction_rad`."""

    x: float
    y: float
    slope_rad: float
    direction_rad: float


@dataclass(frozen=True)
class SlipPatch:
    """A slippery disc of the floor (a wet or dusty patch): there the body moves only
    (1 - slip) of what each wheel turns, (left, right)."""

    x: float
    y: float
    radius_m: float
    slip: tuple[float, float]


def slip_at(patches: tuple[SlipPatch, ...], x: float, y: float) -> tuple[float, float]:
    """(left, right) slip at (x, y): that of the first patch covering it, else none."""
    for p in patches:
        if math.hypot(x - p.x, y - p.y) < p.radius_m:
            return p.slip
    return (0.0, 0.0)


def floor_height(
    bumps: tuple[FloorBump | FloorTilt, ...], x: float, y: float
) -> tuple[float, float, float]:
    """Floor height and its gradient at (x, y): (h metres, dh/dx, dh/dy)."""
    h = gx = gy = 0.0
    for b in bumps:
        if isinstance(b, FloorTilt):
            g = math.tan(b.slope_rad)
            tx, ty = g * math.cos(b.direction_rad), g * math.sin(b.direction_rad)
            h += tx * (x - b.x) + ty * (y - b.y)
            gx, gy = gx + tx, gy + ty
            continue
        dx, dy = x - b.x, y - b.y
        r = math.hypot(dx, dy)
        if r >= b.radius_m:
            continue
        a = math.pi * r / b.radius_m
        h += b.height_m * 0.5 * (1.0 + math.cos(a))
        if r > 1e-12:
            dh_dr = -b.height_m * 0.5 * math.sin(a) * math.pi / b.radius_m
            gx += dh_dr * dx / r
            gy += dh_dr * dy / r
    return h, gx, gy


@dataclass(frozen=True)
class OdometryModel:
    """How the wheel odometry errs.

    Attributes:
        rate_hz: odometry samples (and control ticks) per second.
        wheel_scale: (left, right) measured / true wheel speed (nominal over true radius).
        wheel_base_true_m: the real distance between the wheels' contact points.
        noise_rel: standard deviation of each sample's speed noise, relative to the speed.
    """

    rate_hz: float
    wheel_scale: tuple[float, float]
    wheel_base_true_m: float
    noise_rel: float = 0.01


@dataclass(frozen=True, eq=False)
class FramePose:
    """A frame due at `t_ns`, taken from the body pose `T_world_body` (4, 4) (lifted and
    tilted by bumps) whose planar pose is `pose` (x, y, theta)."""

    t_ns: int
    T_world_body: FloatArray
    pose: tuple[float, float, float]
    floor: str = "0"
    in_lift: bool = False


@dataclass(frozen=True)
class FloorArrival:
    """The robot left the lift at `t_ns` on `floor`, at its true planar `pose`; `announce`:
    its fleet manager tells the site so."""

    t_ns: int
    floor: str
    pose: tuple[float, float, float]
    announce: bool


class SimRobot:
    """One simulated robot.

    Args:
        name: its name.
        start: (x, y, theta) at `t0_ns`.
        route: what it drives.
        odometry: its odometry errors and rate.
        camera_rate_hz: frames per second.
        frame_drop: probability that a frame is lost.
        bumps: floor bumps and tilt.
        slips: slippery patches.
        rng: draws odometry noise and dropped frames.
        t0_ns: start time; frames start at `t0_ns + frame_offset_ns`.
        limits: controller limits.
    """

    def __init__(
        self,
        name: str,
        *,
        start: tuple[float, float, float],
        route: Route,
        odometry: OdometryModel,
        camera_rate_hz: float,
        frame_drop: float,
        bumps: tuple[FloorBump | FloorTilt, ...],
        rng: np.random.Generator,
        t0_ns: int = 0,
        frame_offset_ns: int = 0,
        limits: DriveLimits | None = None,
        slips: tuple[SlipPatch, ...] = (),
        floor: str = "0",
    ) -> None:
        self.name = name
        self.slips = slips
        self.odometry = odometry
        self.bumps = bumps
        self.frame_drop = frame_drop
        self.rng = rng
        self.tick_ns = round(1e9 / odometry.rate_hz)
        self.frame_period_ns = round(1e9 / camera_rate_hz)
        self.follower = RouteFollower(route, limits, tick_s=self.tick_ns * 1e-9)
        self.x, self.y, self.theta = (float(v) for v in start)
        self.t_ns = t0_ns  # time of the state above (always a control tick)
        self._command = (0.0, 0.0)
        self._slip = (0.0, 0.0)
        self._snapshot = (self.t_ns, self.x, self.y, self.theta, self._command, self._slip)
        self._next_frame_ns = t0_ns + frame_offset_ns
        self.paused_until_ns = t0_ns
        self.lift_m = 0.0  # height above the floor while carried
        self._carry_from: tuple[float, float, float] | None = None
        self.kidnaps: list[tuple[int, int]] = []  # (picked up, put down) times, ns
        self.floor = floor
        """The floor it is on (while riding: the floor it boarded on)."""
        self.in_lift = False
        self._lift: Lift | None = None

    def _true_wheels(self, v: float, omega: float) -> tuple[float, float]:
        half = 0.5 * self.odometry.wheel_base_true_m * omega
        return v - half, v + half

    def _arc(
        self,
        state: tuple[int, float, float, float, tuple[float, float], tuple[float, float]],
        t_ns: int,
    ) -> tuple[float, float, float]:
        t0, x, y, theta, command, slip = state
        vl, vr = self._true_wheels(*command)
        vl, vr = vl * (1.0 - slip[0]), vr * (1.0 - slip[1])
        dt_s = (t_ns - t0) * 1e-9
        xe, ye, th = integrate_arc(x, y, theta, vl, vr, dt_s, self.odometry.wheel_base_true_m)
        return float(xe), float(ye), float(th)

    def pose_at(self, t_ns: int) -> tuple[float, float, float]:
        """True planar pose at `t_ns` >= the last tick (the current arc, extended).

        Safe to call from another thread while `advance_to` runs (one consistent snapshot).
        """
        return self._arc(self._snapshot, t_ns)

    def T_world_body(self, x: float, y: float, theta: float, *, lift_m: float = 0.0) -> FloatArray:
        """Body pose (4, 4) on the floor at (x, y, theta): lifted and tilted by bumps and
        the floor's tilt (and `lift_m` higher: carried)."""
        h, gx, gy = floor_height(self.bumps, x, y)
        T = np.eye(4)
        R = rotation_z(theta)
        if gx or gy:
            c, s = math.cos(theta), math.sin(theta)
            pitch = -math.atan(gx * c + gy * s)  # nose up going uphill (REP-103: +pitch = down)
            roll = math.atan(-gx * s + gy * c)  # left side up when the floor rises to the left
            cp, sp, cr, sr = math.cos(pitch), math.sin(pitch), math.cos(roll), math.sin(roll)
            Ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
            Rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
            R = R @ Ry @ Rx
        T[:3, :3] = R
        T[:3, 3] = [x, y, h + lift_m]
        return T

    def _measure(self) -> tuple[float, float]:
        vl, vr = self._true_wheels(*self._command)
        sl, sr = self.odometry.wheel_scale
        noise = self.rng.normal(0.0, self.odometry.noise_rel, 2)
        return vl * sl * (1.0 + noise[0]), vr * sr * (1.0 + noise[1])

    def advance_to(self, t_ns: int) -> list[OdometryMeasured | FramePose | FloorArrival]:
        """Drive up to `t_ns`; the odometry samples and (not dropped) frames due, in time order.

        At equal times the odometry sample comes before the frame.
        """
        out: list[OdometryMeasured | FramePose | FloorArrival] = []
        while True:
            tick = self.t_ns + self.tick_ns
            while self._next_frame_ns < tick and self._next_frame_ns <= t_ns:
                self._add_frame(out, self._next_frame_ns)
            if tick > t_ns:
                return out
            self.x, self.y, self.theta = self._arc(self._snapshot, tick)
            self.t_ns = tick
            self._carry(tick)
            self._ride(out, tick)
            vl, vr = self._measure()
            out.append(OdometryMeasured(tick, vl, vr))
            if tick >= self.paused_until_ns:
                self._command = self.follower.command(tick * 1e-9, self.x, self.y, self.theta)
            else:
                self._command = (0.0, 0.0)
            self._slip = slip_at(self.slips, self.x, self.y) if self.slips else (0.0, 0.0)
            self._snapshot = (tick, self.x, self.y, self.theta, self._command, self._slip)

    def _carry(self, tick_ns: int) -> None:
        """While a kidnap is under way, put the body where the carry has brought it."""
        carry = self.follower.carrying(tick_ns * 1e-9)
        if carry is None:
            return
        step, done = carry
        if self._carry_from is None:
            self._carry_from = (self.x, self.y, self.theta)
            self.kidnaps.append((tick_ns, tick_ns))
        x0, y0, th0 = self._carry_from
        turn = float(wrap_angle(step.theta - th0))
        self.x, self.y = x0 + done * (step.x - x0), y0 + done * (step.y - y0)
        self.theta = float(wrap_angle(th0 + done * turn))
        self.lift_m = step.lift_m * math.sin(math.pi * done)
        if done >= 1.0:
            self._carry_from = None
            self.lift_m = 0.0
            self.kidnaps[-1] = (self.kidnaps[-1][0], tick_ns)

    def _ride(self, out: list[OdometryMeasured | FramePose | FloorArrival], tick_ns: int) -> None:
        """In the lift while the route rides it; on its floor (a `FloorArrival`) after."""
        lift = self.follower.riding()
        if lift is not None:
            self._lift, self.in_lift = lift, True
            return
        if self._lift is not None:
            self.floor, self.in_lift = self._lift.floor, False
            out.append(
                FloorArrival(tick_ns, self.floor, (self.x, self.y, self.theta), self._lift.announce)
            )
            self._lift = None

    def _add_frame(self, out: list[OdometryMeasured | FramePose | FloorArrival], t_ns: int) -> None:
        self._next_frame_ns += self.frame_period_ns
        if self.frame_drop > 0 and self.rng.random() < self.frame_drop:
            return
        pose = self.pose_at(t_ns)
        T = self.T_world_body(*pose, lift_m=self.lift_m)
        out.append(FramePose(t_ns, T, pose, self.floor, self.in_lift))
