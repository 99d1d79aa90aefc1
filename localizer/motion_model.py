"""The motion model for frames without odometry: constant velocity and constant turn rate.

The paper's tracking needs no odometry: its search windows come from the maximum speed, the
frame rate and the scale (Sec. IV-A.1). Here the prediction between two frames is an arc at
the estimated forward speed v and turn rate w (the constant-turn model, eq. (5) with
dT = v dt, dR = w dt), and its uncertainty is honest process noise: a white acceleration
(discrete, piecewise constant over a step) of `accel_sigma_m_s2` along the path and
`angular_accel_sigma_rad_s2` in heading.

(v, w) are estimated by a scalar Kalman filter each, from the change between consecutive
fused fixes (a fix's own covariance, not the pose filter's posterior, which the prediction
itself shaped) and, where the robot has one, from an IMU's rate gyro (z, in the body frame),
which measures w directly:

    predict over dt:   var_v += a_v^2 T dt,  var_w += a_w^2 T dt      (T: accel_duration_s)
    fix pair (dt):     v_m = (p1 - p0) . (cos, sin)(theta_mid) / dt,  R_v = (s0^2 + s1^2) / dt^2
                       w_m = wrap(theta1 - theta0) / dt,              R_w = (t0^2 + t1^2) / dt^2
    gyro:              w = w_z, var_w = gyro_sigma^2 (the gyro measures w itself)
    update:            k = var / (var + R);  x += k (m - x);  var *= 1 - k

Before any fix the robot is taken to be at rest (`start_at_rest`: a parked robot starting
up); its speed then grows at most by `bound_sigmas` x the acceleration x the time since the
start until a fix pair measures it: `speed_bounds` gives the image-motion bound that
identification matches spots with.
Pure: numbers in, numbers out.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from localizer.geometry import wrap_angle

_NS = 1e-9


@dataclass(frozen=True)
class MotionModelConfig:
    """Tuning of the motion model used without odometry (SI units).

    Attributes:
        enabled: predict with the motion model when odometry is silent (else the pose stays
            put between frames, as before).
        silent_odometry_s: odometry counts as absent when no sample arrived for this long
            (or never), seconds.
        accel_sigma_m_s2: standard deviation of the acceleration along the path, m/s^2.
        angular_accel_sigma_rad_s2: ... of the heading's angular acceleration, rad/s^2.
        accel_duration_s: how long an acceleration lasts (the white acceleration's spectral
            density is sigma^2 x this), seconds.
        bound_sigmas: the motion bounds (`speed_bounds`) are this many sigmas.
        gyro_sigma_rad_s: noise of one gyro sample's heading rate, rad/s.
        start_at_rest: before the first fix the robot is at rest (its speed grows by at
            most `bound_sigmas` x the acceleration); False: it may move at its top speed.
        max_fix_gap_s: two fixes further apart than this do not measure the velocity (the
            path between them need not be one arc), seconds.
        snap_output: the output takes each fused fix at once (no smoothing): without
            odometry a correction is mostly motion the model did not foresee.
    """

    enabled: bool = True
    silent_odometry_s: float = 1.0
    accel_sigma_m_s2: float = 1.0
    angular_accel_sigma_rad_s2: float = 3.0
    accel_duration_s: float = 0.3
    bound_sigmas: float = 3.0
    gyro_sigma_rad_s: float = 0.02
    start_at_rest: bool = True
    max_fix_gap_s: float = 0.3
    snap_output: bool = True

    def __post_init__(self) -> None:
        for name in (
            "silent_odometry_s",
            "accel_sigma_m_s2",
            "angular_accel_sigma_rad_s2",
            "accel_duration_s",
            "bound_sigmas",
            "gyro_sigma_rad_s",
            "max_fix_gap_s",
        ):
            v = getattr(self, name)
            if not math.isfinite(v) or v <= 0:
                raise ValueError(f"MotionModelConfig: {name} must be > 0, got {v!r}")


@dataclass(frozen=True)
class ProcessNoise:
    """What a prediction of `dt` adds to the pose covariance: variance of each position
    axis (m^2) and of the heading (rad^2)."""

    var_xy_m2: float
    var_theta_rad2: float


class ConstantVelocity:
    """The estimated forward speed and turn rate, and their variances.

    Args:
        config: tuning.
        max_speed_m_s, max_turn_rad_s: the robot's limits (speeds are clipped to them).
    """

    def __init__(
        self, config: MotionModelConfig, *, max_speed_m_s: float, max_turn_rad_s: float
    ) -> None:
        self.config = config
        self.max_speed = max_speed_m_s
        self.max_turn = max_turn_rad_s
        self.v = 0.0
        self.w = 0.0
        rest = config.start_at_rest
        self.var_v = 0.0 if rest else max_speed_m_s**2
        self.var_w = 0.0 if rest else max_turn_rad_s**2
        self.t_ns: int | None = None  # time of (v, w, var)
        self._at_rest = rest  # no speed measured yet: the start-from-rest bound holds
        self._t_start: int | None = None
        self._fix: tuple[int, float, float, float, float, float] | None = (
            None  # t, x, y, th, s2, t2
        )
        self._gyro_t_ns: int | None = None

    @property
    def has_gyro(self) -> bool:
        """A gyro sample has arrived (w then follows it)."""
        return self._gyro_t_ns is not None

    # -- the model -------------------------------------------------------------------------------
    def predict(self, t_ns: int) -> None:
        """Advance (v, w)'s variance to `t_ns` (the values stay: constant velocity)."""
        if self.t_ns is None:
            self.t_ns = self._t_start = t_ns
            return
        dt = (t_ns - self.t_ns) * _NS
        if dt <= 0:
            return
        self.var_v, self.var_w = self._grown(dt)
        self.t_ns = t_ns

    def _grown(self, dt: float) -> tuple[float, float]:
        """(var_v, var_w) grown over `dt` seconds, within the robot's limits."""
        c = self.config
        T = c.accel_duration_s
        var_v = min(self.var_v + c.accel_sigma_m_s2**2 * T * dt, self.max_speed**2)
        var_w = min(self.var_w + c.angular_accel_sigma_rad_s2**2 * T * dt, self.max_turn**2)
        return var_v, var_w

    def process_noise(self, dt: float) -> ProcessNoise:
        """The pose covariance a prediction of `dt` seconds at (v, w) adds: the velocity's
        variance times dt^2 plus the white acceleration's within the step (q dt^3 / 3,
        q = sigma^2 x `accel_duration_s`), both position axes alike (a body may also slide
        sideways)."""
        c = self.config
        cube = c.accel_duration_s * dt**3 / 3.0
        return ProcessNoise(
            self.var_v * dt * dt + c.accel_sigma_m_s2**2 * cube,
            self.var_w * dt * dt + c.angular_accel_sigma_rad_s2**2 * cube,
        )

    def wheel_speeds(self, wheel_base_m: float) -> tuple[float, float]:
        """(v_left, v_right) that drive the arc (v, w) on a base of `wheel_base_m` (eq. 6
        inverted), m/s."""
        half = 0.5 * self.w * wheel_base_m
        return self.v - half, self.v + half

    def speed_bounds(self, t_ns: int) -> tuple[float, float]:
        """Bounds on the speed (m/s) and the turn rate (rad/s) at `t_ns`, within the robot's
        limits: from rest (no speed measured yet), k sigma of the acceleration times the
        time since the start; else |v| + k sigma, the variance grown to `t_ns`."""
        c = self.config
        k = c.bound_sigmas
        if self._at_rest:
            since = 0.0 if self._t_start is None else max((t_ns - self._t_start) * _NS, 0.0)
            return (
                min(k * c.accel_sigma_m_s2 * since, self.max_speed),
                min(k * c.angular_accel_sigma_rad_s2 * since, self.max_turn),
            )
        dt = 0.0 if self.t_ns is None else max((t_ns - self.t_ns) * _NS, 0.0)
        var_v, var_w = self._grown(dt)
        sv, sw = math.sqrt(var_v), math.sqrt(var_w)
        return min(abs(self.v) + k * sv, self.max_speed), min(abs(self.w) + k * sw, self.max_turn)

    def unpredicted_bounds(self) -> tuple[float, float]:
        """What a prediction at (v, w) may miss, as speeds: `bound_sigmas` x the speed's
        and the turn rate's standard deviations (m/s, rad/s): the search windows' motion
        term without odometry (Sec. IV-A.1's maximum speed, less what the model predicts)."""
        k = self.config.bound_sigmas
        return k * math.sqrt(self.var_v), k * math.sqrt(self.var_w)

    # -- measurements ----------------------------------------------------------------------------
    def fixed(
        self, t_ns: int, x: float, y: float, theta: float, var_xy: float, var_th: float
    ) -> None:
        """A fused fix at `t_ns` (its pose and its own variances): with the previous one, a
        measurement of the mean speed and turn rate between them."""
        self.predict(t_ns)
        prev = self._fix
        self._fix = (t_ns, x, y, theta, var_xy, var_th)
        if prev is None:
            return
        t0, x0, y0, th0, s0, r0 = prev
        dt = (t_ns - t0) * _NS
        if not 0 < dt <= self.config.max_fix_gap_s:
            return
        dth = float(wrap_angle(theta - th0))
        mid = th0 + 0.5 * dth
        v_m = ((x - x0) * math.cos(mid) + (y - y0) * math.sin(mid)) / dt
        self._at_rest = False
        self.v, self.var_v = _scalar_update(self.v, self.var_v, v_m, (s0 + var_xy) / (dt * dt))
        if not self.has_gyro:
            w_m = dth / dt
            self.w, self.var_w = _scalar_update(self.w, self.var_w, w_m, (r0 + var_th) / (dt * dt))
        self.v = min(max(self.v, -self.max_speed), self.max_speed)
        self.w = min(max(self.w, -self.max_turn), self.max_turn)

    def gyro(self, t_ns: int, w_z: float) -> None:
        """A gyro sample: the heading rate, rad/s."""
        self.predict(t_ns)
        self._gyro_t_ns = t_ns
        sigma = self.config.gyro_sigma_rad_s
        # The gyro measures the rate itself, many times a frame: it replaces the estimate
        # (no prior to weigh against; at rest the prior's variance is zero).
        self.w, self.var_w = min(max(w_z, -self.max_turn), self.max_turn), sigma * sigma

    def break_track(self) -> None:
        """The pose was reset (relocalized, re-seeded): the next fix starts a new pair."""
        self._fix = None


def _scalar_update(x: float, var: float, z: float, r: float) -> tuple[float, float]:
    """One scalar Kalman update of (x, var) by a measurement z of variance r."""
    s = var + r
    if s <= 0:
        return z, 0.0
    k = var / s
    return x + k * (z - x), (1.0 - k) * var
