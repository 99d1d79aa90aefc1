"""The body's tilt (roll, pitch) from an IMU's gravity direction: the fix's prior on the floor.

A 1.5-2 deg floor bump tilts the camera: a fix from a pair of landmarks then moves by about
(ceiling - camera) x tilt, 11-13 cm at 2.5 m, although the robot did not move; two landmarks
cannot tell a tilt from a translation (docs/localizer-models.md, "The floor under the
robot"). An accelerometer at rest measures the specific force f = R^T (0, 0, g): with
R_tilt = Ry(pitch) Rx(roll) (as `pose_tilted.level_mounting`),

    f = g (-sin pitch, sin roll cos pitch, cos roll cos pitch)
    roll = atan2(f_y, f_z),   pitch = atan2(-f_x, sqrt(f_y^2 + f_z^2)).

A moving body adds its own acceleration: the forward change of speed along x and the
centripetal v w along y, taken out with the speed and the turn rate the localizer knows
(the odometry's speed and the gyro's rate; without odometry the tilt is not used: the motion
model's speed moves in steps at each fix, and their differences would read as pitch).
The forward acceleration is the difference of two exponential averages of the speed (time
constants tau_1 < tau_2: on a ramp of slope a they lag by a tau_1 and a tau_2, so
a = (fast - slow) / (tau_2 - tau_1)), not the noisy
difference of consecutive samples (1 % speed noise at 100 Hz would be 4 deg of pitch).
Samples whose |f| is further than `max_force_error_m_s2` from g (a jolt) are not used.
The tilt is smoothed with `time_constant_s` and handed to the fix as the floor's tilt
(`solve_pose`'s `floor_prior`): the fix is solved on the tilted body, even from two
landmarks.
Pure: numbers in, numbers out.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

GRAVITY_M_S2 = 9.81
_NS = 1e-9
_SPEED_TAU_S = (0.02, 0.08)  # the speed's two averages (the forward acceleration), seconds


@dataclass(frozen=True)
class ImuTiltConfig:
    """Tuning of the tilt from the IMU's gravity direction.

    Attributes:
        enabled: use an IMU's accelerometer (when the recording or robot has one) for the
            fix's tilt.
        time_constant_s: the tilt is smoothed with this time constant, seconds.
        tilt_sigma_rad: standard deviation of the smoothed tilt (accelerometer noise and
            what is left of the body's own acceleration), radians.
        max_force_error_m_s2: a sample whose specific force differs from g by more than
            this (after the body's acceleration is taken out) is not used, m/s^2.
        max_age_s: a tilt older than this at a frame is not used, seconds.
        height_sigma_m: the body's height above the map's floor, which the IMU does not
            know (a bump lifts it): the prior's standard deviation around 0, metres.
    """

    enabled: bool = True
    time_constant_s: float = 0.03
    tilt_sigma_rad: float = 0.005
    max_force_error_m_s2: float = 0.8
    max_age_s: float = 0.1
    height_sigma_m: float = 0.02

    def __post_init__(self) -> None:
        names = (
            "time_constant_s",
            "tilt_sigma_rad",
            "max_force_error_m_s2",
            "max_age_s",
            "height_sigma_m",
        )
        for name in names:
            v = getattr(self, name)
            if not math.isfinite(v) or v <= 0:
                raise ValueError(f"ImuTiltConfig: {name} must be > 0, got {v!r}")


def tilt_from_gravity(f_x: float, f_y: float, f_z: float) -> tuple[float, float]:
    """(roll, pitch) radians of a body whose specific force at rest is f (body frame)."""
    return math.atan2(f_y, f_z), math.atan2(-f_x, math.hypot(f_y, f_z))


class GravityTilt:
    """The smoothed tilt from accelerometer samples."""

    def __init__(self, config: ImuTiltConfig) -> None:
        self.config = config
        self.roll = 0.0
        self.pitch = 0.0
        self.t_ns: int | None = None
        self._speed: tuple[int, float, float] | None = None  # t, fast and slow speed averages

    def sample(
        self, t_ns: int, accel: tuple[float, float, float], speed_m_s: float, turn_rad_s: float
    ) -> None:
        """An accelerometer sample (body frame, m/s^2) with the body's forward speed and
        turn rate at `t_ns` (to take its own acceleration out)."""
        tau_fast, tau_slow = _SPEED_TAU_S
        if self._speed is None or t_ns <= self._speed[0]:
            self._speed = (t_ns, speed_m_s, speed_m_s)
        else:
            t0, fast, slow = self._speed
            dt = (t_ns - t0) * _NS
            fast += (1.0 - math.exp(-dt / tau_fast)) * (speed_m_s - fast)
            slow += (1.0 - math.exp(-dt / tau_slow)) * (speed_m_s - slow)
            self._speed = (t_ns, fast, slow)
        a_x = (self._speed[1] - self._speed[2]) / (tau_slow - tau_fast)
        f_x, f_y, f_z = accel[0] - a_x, accel[1] - speed_m_s * turn_rad_s, accel[2]
        if abs(math.sqrt(f_x * f_x + f_y * f_y + f_z * f_z) - GRAVITY_M_S2) > (
            self.config.max_force_error_m_s2
        ):
            return
        roll, pitch = tilt_from_gravity(f_x, f_y, f_z)
        if self.t_ns is None:
            self.roll, self.pitch = roll, pitch
        else:
            dt = max((t_ns - self.t_ns) * _NS, 0.0)
            k = 1.0 - math.exp(-dt / self.config.time_constant_s)
            self.roll += k * (roll - self.roll)
            self.pitch += k * (pitch - self.pitch)
        self.t_ns = t_ns

    def at(self, t_ns: int) -> tuple[float, float] | None:
        """(roll, pitch) for a frame at `t_ns`; None without a recent sample."""
        if self.t_ns is None or abs(t_ns - self.t_ns) * _NS > self.config.max_age_s:
            return None
        return self.roll, self.pitch
