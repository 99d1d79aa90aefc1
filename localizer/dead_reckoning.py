"""How the pose moves between fixes: the wheel odometry, or without it the motion model.

- The wheel odometry (`OdometryTrack`: the raw dead-reckoning track and its history)
  drives the filter's prediction (Sec. IV-B, eqs. 5-6); a frame extrapolates it, at the
  last wheel speeds, from the last sample to the frame's time on a copy of the filter.
- Without odometry (none yet, or silent for `MotionModelConfig.silent_odometry_s`), the
  constant-velocity motion model (`ConstantVelocity`: speed and turn rate measured from the
  fixes, the heading rate from an IMU's gyro) drives both instead, with its process noise.
- An IMU's gravity direction gives the body's tilt to the fixes (`GravityTilt`), while
  measured wheel speeds say the body's own acceleration.

Sans-I/O: time arrives as an argument.
"""

from __future__ import annotations

import math

from localizer.after_frame import AfterFrame
from localizer.config import LocalizerConfig
from localizer.events import ImuMeasured
from localizer.geometry import wrap_angle
from localizer.imu_tilt import GravityTilt
from localizer.motion_model import ConstantVelocity
from localizer.odometry_track import OdometryTrack
from localizer.pose import PoseFix
from localizer.pose_filter import PoseFilter
from localizer.robot import RobotGeometry

_NS = 1e-9


class DeadReckoning:
    """The odometry, the motion model and the IMU's tilt (see the module docstring).

    Args:
        config: the localizer's tuning (`fusion`, `motion`, `imu`).
        robot: wheel base and maximum speed.
        max_turn_rad_s: the maximum turn rate, rad/s.

    Attributes:
        odometry: the raw dead-reckoning track and its history.
        motion: the motion model (speed and turn rate for frames without odometry).
        gravity: the body's tilt from an IMU.
    """

    def __init__(self, config: LocalizerConfig, robot: RobotGeometry, max_turn_rad_s: float):
        self.config = config
        self.robot = robot
        self.max_turn_rad_s = max_turn_rad_s
        self.odometry = OdometryTrack(
            robot.wheel_base,
            config.fusion.odometry_history_s,
            interval_mean=config.fusion.odometry_interval_mean,
        )
        self.motion = ConstantVelocity(
            config.motion, max_speed_m_s=robot.max_speed, max_turn_rad_s=max_turn_rad_s
        )
        self.gravity = GravityTilt(config.imu)

    def model_drives(self, t_ns: int) -> bool:
        """Whether the motion model predicts instead of the odometry: it is on and no
        odometry sample arrived within `MotionModelConfig.silent_odometry_s` (or ever)."""
        mc = self.config.motion
        t_sample = self.odometry.t_sample_ns
        return mc.enabled and (t_sample is None or (t_ns - t_sample) * _NS > mc.silent_odometry_s)

    def fresh(self, t_ns: int) -> bool:
        """An odometry sample arrived within `FusionConfig.odometry_stale_s` of `t_ns`."""
        t_sample = self.odometry.t_sample_ns
        return (
            t_sample is not None and (t_ns - t_sample) * _NS < self.config.fusion.odometry_stale_s
        )

    def extrapolate(
        self, t_ns: int, filt: PoseFilter | None, t_filter_ns: int
    ) -> PoseFilter | None:
        """Extrapolate odometry (raw, and a copy of `filt`, whose state is of `t_filter_ns`)
        to `t_ns` at the last wheel speeds; returns the copy (None: no filter), `filt`
        stays as it was. Without odometry (`model_drives`) the motion model's speed and
        turn rate drive both instead, with its process noise."""
        v_left, v_right = self.odometry.speeds
        model = self.model_drives(t_ns)
        if model:
            self.motion.predict(t_ns)
            v_left, v_right = self.motion.wheel_speeds(self.robot.wheel_base)
        self.odometry.step(t_ns, v_left, v_right)
        if filt is None:
            return None
        work = filt.copy()
        dt = (t_ns - t_filter_ns) * _NS
        if dt > 0 and model:
            q = self.motion.process_noise(dt)
            work.predict_motion(self.motion.v, self.motion.w, dt, q.var_xy_m2, q.var_theta_rad2)
        elif dt > 0:
            work.predict(v_left, v_right, dt)
        return work

    def fixed(
        self,
        t_ns: int,
        used: tuple[int, ...],
        fused: PoseFix | None,
        filt: PoseFilter | None,
        after: AfterFrame,
    ) -> None:
        """A frame fused a fix of the landmarks `used`: the motion model measures the speed
        and turn rate from it and the one before (the fix's own pose and covariance, when
        `fused`, the tracker's last fused fix, is it; after a reset, the filter's, which is
        the fix's). With odometry driving, the model only learns for later: that is done
        after the frame's pose is out (`after`)."""
        if fused is not None and tuple(fused.landmark_ids) == tuple(used):
            x, y, th, cov = fused.x, fused.y, fused.theta, fused.covariance
        elif filt is not None:
            x, y, th = filt.pose
            cov = filt.covariance
        else:
            return
        var_xy = 0.5 * float(cov[0, 0] + cov[1, 1])
        var_th = float(cov[2, 2])
        motion = self.motion
        if not self.model_drives(t_ns):
            after.defer(lambda: motion.fixed(t_ns, x, y, th, var_xy, var_th))
            return
        motion.fixed(t_ns, x, y, th, var_xy, var_th)
        if self.config.motion.snap_output and filt is not None:
            # without odometry a fix's correction is mostly motion the model did not
            # foresee (a turn begun or ended): smoothing it would only make a lag
            filt.snap_output()

    def imu(self, e: ImuMeasured) -> None:
        """An IMU sample: its heading rate drives the motion model (without odometry); its
        gravity direction gives the body's tilt to the fixes (`imu_tilt`)."""
        self.motion.gyro(e.t_ns, e.gyro[2])
        # The body's own acceleration must come out of the specific force: only measured
        # wheel speeds say it (the motion model's speed moves in steps at each fix, and its
        # differences read as degrees of pitch), so without odometry the tilt is not used.
        if self.config.imu.enabled and not self.model_drives(e.t_ns):
            speed = 0.5 * (self.odometry.speeds[0] + self.odometry.speeds[1])
            self.gravity.sample(e.t_ns, e.accel, speed, e.gyro[2])

    def tilt_at(self, t_ns: int) -> tuple[float, float] | None:
        """The body's (roll, pitch) from the IMU at `t_ns`, radians (None: none known)."""
        return self.gravity.at(t_ns) if self.config.imu.enabled else None

    def since_sample_s(self, t_ns: int, fresh: bool) -> float:
        """Time from the last odometry sample to `t_ns` when the odometry is `fresh`, at
        most 1.5 sample intervals, seconds (0 otherwise)."""
        track = self.odometry
        since = 0.0
        if fresh and track.t_sample_ns is not None:
            since = (t_ns - track.t_sample_ns) * _NS
            since = min(since, 1.5 * (track.interval_s or since))
        return since

    def unpredicted_bounds(self, t_ns: int) -> tuple[float, float] | None:
        """While the motion model drives, the speed and turn rate it may have missed
        (`ConstantVelocity.unpredicted_bounds`); None with odometry."""
        return self.motion.unpredicted_bounds() if self.model_drives(t_ns) else None

    def motion_bound_px(
        self, t0_ns: int, t1_ns: int, scale_px_per_m: float, half_diagonal_px: float
    ) -> float:
        """Bound on a spot's image motion between two times: from odometry (with 20 % slack)
        when there is any, else from the maximum speed and turn rate."""
        track = self.odometry
        scale = scale_px_per_m
        if track.t_sample_ns is None:
            dt = abs(t1_ns - t0_ns) * _NS
            speed, omega = self.robot.max_speed, self.max_turn_rad_s
            if self.config.motion.enabled:  # the motion model's bounds (from rest at start)
                speed, omega = self.motion.speed_bounds(max(t0_ns, t1_ns))
            return dt * (speed * scale + omega * half_diagonal_px)
        a, b = track.pose_at(t0_ns), track.pose_at(t1_ns)
        move = math.hypot(b[0] - a[0], b[1] - a[1]) * scale
        turn = abs(float(wrap_angle(b[2] - a[2]))) * half_diagonal_px
        return 1.2 * (move + turn) + 1.0
