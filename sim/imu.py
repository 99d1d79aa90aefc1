"""A simulated IMU: the body's heading rate and specific force, as a robot's IMU reports them.

Sampled at every control tick (the odometry rate) from the robot's true motion: the gyro
gives the mean angular rate over the tick (the planar heading change over the tick; a bump's
roll and pitch rates are left out), plus a constant bias drawn once and white noise; the
accelerometer gives gravity in the body frame (the body tilted by bumps and the floor's tilt,
so a tilted camera is seen here too) plus the planar acceleration (the tick's change of
speed along the body's x, and the centripetal v w along y), plus white noise. Axes are the
body's (REP-103), so the recording's `imu0/sensor.yaml` holds an identity T_BS.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from localizer.events import ImuMeasured
from localizer.geometry import wrap_angle
from localizer.types import FloatArray

GRAVITY_M_S2 = 9.81


@dataclass(frozen=True)
class ImuSpec:
    """How the IMU errs (scenario `imu:` of a robot).

    Attributes:
        gyro_noise_rad_s: standard deviation of one sample's rate noise, rad/s.
        gyro_bias_rad_s: standard deviation of the constant bias drawn for a run, rad/s.
        accel_noise_m_s2: standard deviation of one sample's specific-force noise, m/s^2.
    """

    gyro_noise_rad_s: float = 0.003
    gyro_bias_rad_s: float = 0.002
    accel_noise_m_s2: float = 0.02


class SimImu:
    """One robot's IMU: call `sample` at every tick with the true state."""

    def __init__(self, spec: ImuSpec, rng: np.random.Generator) -> None:
        self.spec = spec
        self.rng = rng
        self.bias = float(rng.normal(0.0, spec.gyro_bias_rad_s)) if spec.gyro_bias_rad_s else 0.0
        self._last: tuple[int, float, float, float, float] | None = None  # t, x, y, th, v

    def sample(
        self, t_ns: int, pose: tuple[float, float, float], T_world_body: FloatArray
    ) -> ImuMeasured | None:
        """The sample at tick `t_ns` (None for the first tick: no interval yet)."""
        x, y, th = pose
        last = self._last
        if last is None or t_ns <= last[0]:
            self._last = (t_ns, x, y, th, 0.0)
            return None
        t0, x0, y0, th0, v0 = last
        dt = (t_ns - t0) * 1e-9
        w = float(wrap_angle(th - th0)) / dt
        v = math.hypot(x - x0, y - y0) / dt
        mid = th0 + 0.5 * float(wrap_angle(th - th0))
        if (x - x0) * math.cos(mid) + (y - y0) * math.sin(mid) < 0:
            v = -v
        self._last = (t_ns, x, y, th, v)
        s = self.spec
        R = np.asarray(T_world_body, dtype=np.float64)[:3, :3]
        f = R.T @ np.array([0.0, 0.0, GRAVITY_M_S2])
        f += np.array([(v - v0) / dt, v * w, 0.0])
        f += self.rng.normal(0.0, s.accel_noise_m_s2, 3) if s.accel_noise_m_s2 else 0.0
        gz = (
            w
            + self.bias
            + (float(self.rng.normal(0.0, s.gyro_noise_rad_s)) if s.gyro_noise_rad_s else 0.0)
        )
        return ImuMeasured(t_ns, (0.0, 0.0, gz), (float(f[0]), float(f[1]), float(f[2])))
