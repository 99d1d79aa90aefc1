"""What a simulated robot drives: a route of steps (go to a point, wait, turn, sweep the
heading, drive a velocity command), followed by a simple closed-loop controller on the true
pose, one command (v, omega) per control tick.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from localizer.geometry import wrap_angle


@dataclass(frozen=True)
class Goto:
    """Drive to (x, y), metres, at up to `speed_mps` (turning on the spot first if needed)."""

    x: float
    y: float
    speed_mps: float


@dataclass(frozen=True)
class Wait:
    """Stand still for `seconds` (a parked stretch: jitter measurements, stop-and-go)."""

    seconds: float


@dataclass(frozen=True)
class TurnTo:
    """Turn on the spot to the heading `theta`, radians (REP-103)."""

    theta: float


@dataclass(frozen=True)
class Drive:
    """A velocity command: `v_mps` forward and `omega_radps` turn rate for `seconds`."""

    seconds: float
    v_mps: float
    omega_radps: float


@dataclass(frozen=True)
class Kidnap:
    """The robot is lifted and put down elsewhere: carried for `carry_s` (its wheels still,
    its camera `lift_m` higher at mid-carry) from wherever it is to (x, y, theta)."""

    x: float
    y: float
    theta: float
    carry_s: float = 2.0
    lift_m: float = 0.3


@dataclass(frozen=True)
class Lift:
    """Ride the lift (standing in its cabin, where the camera sees the cabin's ceiling and no
    landmark) for `ride_s`, and leave it on `floor`. `announce`: the fleet manager tells
    the site the robot is on that floor as it leaves (else the site must notice)."""

    floor: str
    ride_s: float = 8.0
    announce: bool = True


Step = Goto | Wait | TurnTo | Drive | Kidnap | Lift


@dataclass(frozen=True)
class Route:
    """Steps driven in order; from the first again when `loop`."""

    steps: tuple[Step, ...]
    loop: bool = False


def heading_sweep(start_theta: float, step_rad: float, dwell_s: float) -> list[Step]:
    """A full turn on the spot in steps of `step_rad`, standing `dwell_s` at each heading."""
    count = max(round(2 * math.pi / step_rad), 1)
    out: list[Step] = []
    for k in range(1, count + 1):
        out += [TurnTo(float(wrap_angle(start_theta + k * step_rad))), Wait(dwell_s)]
    return out


@dataclass(frozen=True)
class DriveLimits:
    """Controller gains and limits.

    Attributes:
        max_omega_radps: fastest turn.
        accel_mps2: forward acceleration limit.
        heading_gain: turn rate per radian of heading error, 1/s.
        distance_gain: approach speed per metre of remaining distance, 1/s.
        turn_in_place_rad: heading error above which the robot stops and turns.
        position_tolerance_m: a goal is reached within this distance.
        heading_tolerance_rad: a turn is done within this error.
        angular_accel_radps2: the turn rate changes at most this fast (None: at once, as
            an ideal controller; a real base needs 0.2-0.5 s to reach a fast turn).
        brake_mps2: the forward speed drops at most this fast (None: at once).
    """

    max_omega_radps: float = 1.5
    accel_mps2: float = 1.0
    heading_gain: float = 3.0
    distance_gain: float = 1.5
    turn_in_place_rad: float = 0.4
    position_tolerance_m: float = 0.01
    heading_tolerance_rad: float = 0.003
    angular_accel_radps2: float | None = None
    brake_mps2: float | None = None


class RouteFollower:
    """Turns a route into velocity commands, one control tick at a time."""

    def __init__(
        self, route: Route, limits: DriveLimits | None = None, *, tick_s: float = 0.01
    ) -> None:
        self.route = route
        self.tick_s = tick_s
        self.limits = limits or DriveLimits()
        self._index = 0
        self._step_started_s: float | None = None
        self._v = 0.0
        self._out = (0.0, 0.0)  # the last command given (rate limits)

    @property
    def finished(self) -> bool:
        return self._index >= len(self.route.steps)

    def upcoming(self, count: int = 4) -> tuple[tuple[float, float], ...]:
        """The next `count` points the route drives to, (x, y) in metres, from the step
        under way (what a fleet manager's order holds: the nodes still to be reached)."""
        steps = self.route.steps
        if not steps or count <= 0:
            return ()
        out: list[tuple[float, float]] = []
        index = self._index
        for _ in range(len(steps)):
            if index >= len(steps):
                if not self.route.loop:
                    break
                index = 0
            step = steps[index]
            if isinstance(step, Goto):
                out.append((step.x, step.y))
                if len(out) >= count:
                    break
            elif isinstance(step, Kidnap | Drive | Lift):
                break  # not a route a fleet manager plans (a lift: on another floor)
            index += 1
        return tuple(out)

    def carrying(self, t_s: float) -> tuple[Kidnap, float] | None:
        """The kidnap under way at `t_s` and the share of its carry done (0..1), or None."""
        if self.finished or self._step_started_s is None:
            return None
        step = self.route.steps[self._index]
        if not isinstance(step, Kidnap):
            return None
        return step, min(1.0, (t_s - self._step_started_s) / step.carry_s)

    def riding(self) -> Lift | None:
        """The lift ride under way (the step the robot is at), or None."""
        if self.finished or self._step_started_s is None:
            return None
        step = self.route.steps[self._index]
        return step if isinstance(step, Lift) else None

    def _next(self, t_s: float) -> None:
        self._index += 1
        self._step_started_s = t_s
        if self.finished and self.route.loop and self.route.steps:
            self._index = 0

    def command(self, t_s: float, x: float, y: float, theta: float) -> tuple[float, float]:
        """(v m/s, omega rad/s) to hold until the next tick, from the true pose at `t_s`,
        within the turn-rate and braking limits when set."""
        v, w = self._command(t_s, x, y, theta)
        lim = self.limits
        v0, w0 = self._out
        if lim.angular_accel_radps2 is not None:
            dw = lim.angular_accel_radps2 * self.tick_s
            w = min(max(w, w0 - dw), w0 + dw)
        if lim.brake_mps2 is not None and abs(v) < abs(v0):
            dv = lim.brake_mps2 * self.tick_s
            v = v0 - dv if v0 - dv > v and v0 > 0 else (v0 + dv if v0 + dv < v and v0 < 0 else v)
            self._v = v
        self._out = (v, w)
        return v, w

    def _command(self, t_s: float, x: float, y: float, theta: float) -> tuple[float, float]:
        """`command` before the rate limits."""
        lim = self.limits
        for _ in range(len(self.route.steps) + 1):  # skip finished steps within one tick
            if self.finished:
                self._v = 0.0
                return 0.0, 0.0
            if self._step_started_s is None:
                self._step_started_s = t_s
            step = self.route.steps[self._index]
            elapsed = t_s - self._step_started_s
            if isinstance(step, Wait):
                if elapsed < step.seconds:
                    self._v = 0.0
                    return 0.0, 0.0
            elif isinstance(step, Lift):
                if elapsed < step.ride_s:
                    self._v = 0.0
                    return 0.0, 0.0
            elif isinstance(step, Kidnap):
                if elapsed < step.carry_s:
                    self._v = 0.0
                    return 0.0, 0.0
            elif isinstance(step, Drive):
                if elapsed < step.seconds:
                    self._v = step.v_mps
                    return step.v_mps, step.omega_radps
            elif isinstance(step, TurnTo):
                err = float(wrap_angle(step.theta - theta))
                if abs(err) > lim.heading_tolerance_rad:
                    self._v = 0.0
                    return 0.0, self._turn(err, minimum=0.03)
            else:
                dx, dy = step.x - x, step.y - y
                dist = math.hypot(dx, dy)
                if dist > lim.position_tolerance_m:
                    err = float(wrap_angle(math.atan2(dy, dx) - theta))
                    if abs(err) > lim.turn_in_place_rad:
                        self._v = 0.0
                        return 0.0, self._turn(err, minimum=0.05)
                    target = min(step.speed_mps, max(0.05, lim.distance_gain * dist))
                    return self._accelerate(target * math.cos(err)), self._turn(err, minimum=0.0)
            self._next(t_s)
        self._v = 0.0
        return 0.0, 0.0

    def _turn(self, err: float, *, minimum: float) -> float:
        lim = self.limits
        w = max(min(lim.heading_gain * err, lim.max_omega_radps), -lim.max_omega_radps)
        return math.copysign(max(abs(w), minimum), err) if err != 0 else 0.0

    def _accelerate(self, target: float) -> float:
        step = self.limits.accel_mps2 * self.tick_s
        self._v = min(target, self._v + step) if target > self._v else target
        return self._v
