"""Mounting calibration: where the camera sits on the robot (`T_body_camera`, EuRoC `T_BS`).

The paper assumes the optical centre lies on the robot's rotation axis; real robots rarely
have it there. Here the robot turns in place and drives a short straight line under known
landmarks; from each frame the camera's world pose is measured (`camera_pose_from_landmarks`)
and the mounting follows:

- Turn in place: the body stays at p0 while its heading theta_k changes, so the camera centre
  c_k = p0 + R(theta_k) o moves on a circle about the axle midpoint (o: the offset in the body
  frame). With the camera yaw psi_k = theta_k + yaw this is linear in (p0, o'):
  c_k = p0 + R(psi_k) o',  o' = R(-yaw) o, solved by least squares (a circle fit that also
  uses the measured angles).
- Straight line: the body heading is the direction of travel of the camera centres (the wheel
  speeds say forward or backward), so yaw = psi - heading.
- Then o = R(yaw) o', the height is the camera's mean height above the floor (z = 0), and the
  full rotation (with any tilt) is the mean of R_z(theta_k)^T R_world_camera_k.

Odometry segments the frames into turning and straight driving (wheel speeds interpolated at
the frame times) and cross-checks the turn angle. Pure math: numpy in, dataclasses out.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from calibration.camera_pose import camera_pose_from_landmarks
from localizer.camera import CameraModel, T_body_camera_upward
from localizer.geometry import rotation_2d, rotation_z, wrap_angle
from localizer.landmark_map import LandmarkMap
from localizer.odometry import odometry_increments
from localizer.types import BoolArray, FloatArray

_R_UP = T_body_camera_upward()[:3, :3]  # camera axes of the reference (yaw 0) mounting


@dataclass(frozen=True)
class MountingConfig:
    """Tuning of the mounting calibration.

    Attributes:
        turn_max_speed_m_s: turning in place: |forward speed| at most this, m/s ...
        turn_min_rate_rad_s: ... and |turn rate| at least this, rad/s.
        straight_min_speed_m_s: driving straight: |forward speed| at least this, m/s ...
        straight_max_rate_rad_s: ... and |turn rate| at most this, rad/s.
        min_turn_angle_rad: the turn must sweep at least this angle (camera yaw range).
        min_turn_frames: fewest frames while turning.
        min_straight_length_m: the straight segments must span at least this distance.
        min_straight_frames: fewest frames while driving straight.
        max_circle_rms_m: the turning camera centres must lie on one circle within this RMS.
        max_frame_rms_px: frames whose landmark reprojection RMS exceeds this are dropped.
        max_height_deviation_m: frames whose camera height differs from the median of all
            frames by more than this are dropped (on a floor the camera keeps its height; a
            pose far off it is a wrong P3P branch or misidentified landmarks).
    """

    turn_max_speed_m_s: float = 0.01
    turn_min_rate_rad_s: float = 0.05
    straight_min_speed_m_s: float = 0.02
    straight_max_rate_rad_s: float = 0.01
    min_turn_angle_rad: float = np.pi / 2
    min_turn_frames: int = 8
    min_straight_length_m: float = 0.3
    min_straight_frames: int = 5
    max_circle_rms_m: float = 0.02
    max_frame_rms_px: float = 3.0
    max_height_deviation_m: float = 0.03


@dataclass(frozen=True, eq=False)
class MountingCalibration:
    """The estimated mounting.

    Attributes:
        T_body_camera: body-from-camera transform, shape (4, 4) (EuRoC `T_BS`).
        yaw_rad: rotation of the camera about the vertical relative to the reference
            mounting `T_body_camera_upward()` (image top = robot front at 0): the heading
            of R_body_camera @ R_up^T (equal to the `yaw` of `T_body_camera_upward` when
            there is no tilt; they differ by the tilt's square otherwise).
        offset_xy_m: optical centre's offset from the axle midpoint, body frame, shape (2,).
        height_m: optical centre's height above the floor.
        yaw_std_rad: 1-sigma of yaw_rad.
        offset_std_m: 1-sigma of offset_xy_m, shape (2,).
        turn_centre_world: where the axle midpoint stood during the turn, shape (2,).
        circle_residuals_m: per turning frame, distance of the camera centre from its fitted
            place on the circle, shape (K_turn,).
        line_residuals_m: per straight frame, distance from the fitted line, shape (K_line,).
        turn_angle_camera_rad: the turn as the camera measured it.
        turn_angle_odometry_rad: the same turn from the wheel speeds (a check of the wheel
            base: their ratio is the odometry's turn scale error).
        frames_turn, frames_straight, frames_dropped: frames used in each role or dropped.
    """

    T_body_camera: FloatArray
    yaw_rad: float
    offset_xy_m: FloatArray
    height_m: float
    yaw_std_rad: float
    offset_std_m: FloatArray
    turn_centre_world: FloatArray
    circle_residuals_m: FloatArray
    line_residuals_m: FloatArray
    turn_angle_camera_rad: float
    turn_angle_odometry_rad: float
    frames_turn: int
    frames_straight: int
    frames_dropped: int = 0

    def to_dict(self) -> dict[str, object]:
        """JSON-ready mapping (angles also in degrees)."""
        return {
            "T_BS": {"rows": 4, "cols": 4, "data": [float(x) for x in self.T_body_camera.ravel()]},
            "yaw_deg": float(np.degrees(self.yaw_rad)),
            "yaw_std_deg": float(np.degrees(self.yaw_std_rad)),
            "offset_xy_m": [float(x) for x in self.offset_xy_m],
            "offset_std_m": [float(x) for x in self.offset_std_m],
            "height_m": self.height_m,
            "circle_rms_m": float(np.sqrt(np.mean(self.circle_residuals_m**2))),
            "line_rms_m": float(np.sqrt(np.mean(self.line_residuals_m**2))),
            "turn_angle_camera_deg": float(np.degrees(self.turn_angle_camera_rad)),
            "turn_angle_odometry_deg": float(np.degrees(self.turn_angle_odometry_rad)),
            "frames_turn": self.frames_turn,
            "frames_straight": self.frames_straight,
            "frames_dropped": self.frames_dropped,
        }


def camera_yaw(T_world_camera: FloatArray) -> FloatArray:
    """Heading of the camera's reference axes: psi = body heading + mounting yaw.

    Args:
        T_world_camera: shape (K, 4, 4).

    Returns:
        shape (K,), radians.
    """
    R = np.asarray(T_world_camera)[:, :3, :3] @ _R_UP.T
    return np.arctan2(R[:, 1, 0], R[:, 0, 0])


def estimate_mounting(
    t_ns: npt.ArrayLike,
    T_world_camera: npt.ArrayLike,
    odom_t_ns: npt.ArrayLike,
    v_left: npt.ArrayLike,
    v_right: npt.ArrayLike,
    *,
    wheel_base_m: float,
    config: MountingConfig | None = None,
    frames_dropped: int = 0,
) -> MountingCalibration:
    """Estimate the camera mounting from camera poses during a turn in place and a straight.

    Args:
        t_ns: frame times, shape (K,), nanoseconds.
        T_world_camera: the camera's measured world pose per frame, shape (K, 4, 4).
        odom_t_ns: odometry sample times, shape (M,), nanoseconds, increasing.
        v_left, v_right: wheel speeds at those times, m/s, shape (M,).
        wheel_base_m: distance between the wheels, metres.
        config: tuning.
        frames_dropped: frames the caller already dropped (reported back).

    Raises:
        ValueError: mismatched shapes, too little turning or straight driving, or a turn that
            was not in place (the camera centres do not lie on one circle).
    """
    cfg = config or MountingConfig()
    t = np.asarray(t_ns, dtype=np.float64).reshape(-1)
    T = np.asarray(T_world_camera, dtype=np.float64).reshape(-1, 4, 4)
    to = np.asarray(odom_t_ns, dtype=np.float64).reshape(-1)
    vl = np.asarray(v_left, dtype=np.float64).reshape(-1)
    vr = np.asarray(v_right, dtype=np.float64).reshape(-1)
    if len(t) != len(T):
        raise ValueError(f"mounting: {len(t)} frame times but {len(T)} camera poses")
    if not len(to) == len(vl) == len(vr) or len(to) < 2:
        raise ValueError("mounting: odometry needs matching times and wheel speeds (>= 2)")
    if np.any(np.diff(to) <= 0):
        raise ValueError("mounting: odometry times must increase")
    if not np.isfinite(wheel_base_m) or wheel_base_m <= 0:
        raise ValueError(f"mounting: wheel base must be positive, got {wheel_base_m!r}")
    v_any, omega_any = odometry_increments(
        np.interp(t, to, vl), np.interp(t, to, vr), 1.0, wheel_base_m
    )
    v, omega = np.asarray(v_any, dtype=np.float64), np.asarray(omega_any, dtype=np.float64)
    turning = (np.abs(v) <= cfg.turn_max_speed_m_s) & (np.abs(omega) >= cfg.turn_min_rate_rad_s)
    straight = (np.abs(v) >= cfg.straight_min_speed_m_s) & (
        np.abs(omega) <= cfg.straight_max_rate_rad_s
    )
    centres = T[:, :2, 3]
    psi = camera_yaw(T)

    # turn in place: c_k = p0 + R(psi_k) o'
    it = np.flatnonzero(turning)
    psi_turn = np.unwrap(psi[it])
    sweep = float(np.ptp(psi_turn)) if len(it) else 0.0
    if len(it) < cfg.min_turn_frames or sweep < cfg.min_turn_angle_rad:
        raise ValueError(
            f"mounting: the robot must turn in place through at least "
            f"{np.degrees(cfg.min_turn_angle_rad):.0f} deg over {cfg.min_turn_frames} frames; "
            f"got {len(it)} turning frames sweeping {np.degrees(sweep):.0f} deg"
        )
    c, s = np.cos(psi[it]), np.sin(psi[it])
    A = np.zeros((2 * len(it), 4))
    A[0::2] = np.column_stack([np.ones_like(c), np.zeros_like(c), c, -s])
    A[1::2] = np.column_stack([np.zeros_like(c), np.ones_like(c), s, c])
    b = centres[it].reshape(-1)
    x, *_ = np.linalg.lstsq(A, b, rcond=None)
    resid = (b - A @ x).reshape(-1, 2)
    circle_res = np.linalg.norm(resid, axis=1)
    circle_rms = float(np.sqrt(np.mean(circle_res**2)))
    if circle_rms > cfg.max_circle_rms_m:
        raise ValueError(
            f"mounting: the turning camera positions are {100 * circle_rms:.1f} cm RMS off one "
            "circle: the robot must turn in place (wheels at opposite speeds) at one spot"
        )
    dof = max(2 * len(it) - 4, 1)
    cov_x = float(np.sum(resid**2)) / dof * np.linalg.inv(A.T @ A)
    p0, o_prime, cov_o_prime = x[:2], x[2:], cov_x[2:, 2:]

    # straight driving: heading = direction of travel; yaw = psi - heading
    yaw, yaw_var, line_res = _yaw_from_straight(t, centres, psi, v, straight, cfg)

    R = rotation_2d(yaw)
    offset = R @ o_prime
    J = rotation_2d(yaw + np.pi / 2) @ o_prime  # d(R(yaw) o') / d yaw
    cov_o = R @ cov_o_prime @ R.T + np.outer(J, J) * yaw_var

    used = np.concatenate([it, np.flatnonzero(straight)])
    theta = psi[used] - yaw
    M = sum(rotation_z(-th) @ T[k, :3, :3] for th, k in zip(theta, used, strict=True))
    U, _, Vt = np.linalg.svd(M)
    R_body_camera = U @ np.diag([1.0, 1.0, np.linalg.det(U @ Vt)]) @ Vt
    T_bc = np.eye(4)
    T_bc[:3, :3] = R_body_camera
    T_bc[:3, 3] = [offset[0], offset[1], float(np.mean(T[used, 2, 3]))]

    odo_turn = _odometry_turn(to, vl, vr, wheel_base_m, t[it[0]], t[it[-1]])
    return MountingCalibration(
        T_body_camera=T_bc,
        yaw_rad=float(wrap_angle(yaw)),
        offset_xy_m=offset,
        height_m=float(T_bc[2, 3]),
        yaw_std_rad=float(np.sqrt(yaw_var)),
        offset_std_m=np.sqrt(np.diag(cov_o)),
        turn_centre_world=np.asarray(p0, dtype=np.float64),
        circle_residuals_m=circle_res,
        line_residuals_m=line_res,
        turn_angle_camera_rad=float(psi_turn[-1] - psi_turn[0]),
        turn_angle_odometry_rad=odo_turn,
        frames_turn=len(it),
        frames_straight=int(np.sum(straight)),
        frames_dropped=frames_dropped,
    )


def _yaw_from_straight(
    t: FloatArray,
    centres: FloatArray,
    psi: FloatArray,
    v: FloatArray,
    straight: BoolArray,
    cfg: MountingConfig,
) -> tuple[float, float, FloatArray]:
    """Mounting yaw and its variance from the straight segments, with line residuals."""
    idx = np.flatnonzero(straight)
    # contiguous runs of straight frames, each with one heading
    runs = np.split(idx, np.flatnonzero(np.diff(idx) > 1) + 1) if len(idx) else []
    estimates: list[tuple[float, float, float]] = []  # (yaw, variance, length)
    residuals: list[FloatArray] = []
    for run in runs:
        if len(run) < 3:
            continue
        p = centres[run]
        mean = p.mean(axis=0)
        _, _, Vt = np.linalg.svd(p - mean, full_matrices=False)
        d = Vt[0]
        along = (p - mean) @ d
        if np.corrcoef(t[run], along)[0, 1] < 0:
            d = -d  # d points along the travel in time
            along = -along
        perp = (p - mean) @ np.array([-d[1], d[0]])
        length = float(np.ptp(along))
        heading = float(np.arctan2(d[1], d[0]))
        if np.mean(v[run]) < 0:
            heading += np.pi  # reversing: the body faces against the travel
        dpsi = wrap_angle(psi[run] - heading)
        yaw = float(np.arctan2(np.mean(np.sin(dpsi)), np.mean(np.cos(dpsi))))
        dof = max(len(run) - 2, 1)
        var_dir = float(np.sum(perp**2)) / dof / max(float(np.sum(along**2)), 1e-12)
        var_psi = float(np.var(wrap_angle(dpsi - yaw))) / len(run)
        estimates.append((yaw, var_dir + var_psi, length))
        residuals.append(np.abs(perp))
    total = sum(e[2] for e in estimates)
    frames = sum(len(r) for r in residuals)
    if total < cfg.min_straight_length_m or frames < cfg.min_straight_frames:
        raise ValueError(
            f"mounting: the robot must drive straight for at least {cfg.min_straight_length_m} m "
            f"over {cfg.min_straight_frames} frames; got {total:.2f} m over {frames} frames"
        )
    w = np.array([1.0 / max(e[1], 1e-16) for e in estimates])
    yaws = np.array([e[0] for e in estimates])
    ref = yaws[np.argmax(w)]
    yaw = float(ref + np.sum(w * wrap_angle(yaws - ref)) / np.sum(w))
    return yaw, float(1.0 / np.sum(w)), np.concatenate(residuals)


def _odometry_turn(
    to: FloatArray, vl: FloatArray, vr: FloatArray, wheel_base: float, t0: float, t1: float
) -> float:
    """Heading change from the wheel speeds between t0 and t1 (trapezoidal rule), radians."""
    inside = (to > t0) & (to < t1)
    ts = np.concatenate([[t0], to[inside], [t1]])
    _, omega = odometry_increments(np.interp(ts, to, vl), np.interp(ts, to, vr), 1.0, wheel_base)
    return float(np.trapezoid(omega, ts * 1e-9))


def mounting_from_observations(
    camera: CameraModel,
    landmark_map: LandmarkMap,
    detections: Sequence[tuple[int, Sequence[int], npt.ArrayLike]],
    odometry: Sequence[tuple[int, float, float]],
    *,
    wheel_base_m: float,
    config: MountingConfig | None = None,
) -> MountingCalibration:
    """Estimate the mounting from what the robot saw and how its wheels turned.

    Drive the robot under at least three (better four or more) known landmarks: turn in place
    by half a turn or more, stop, then drive straight for half a metre or more.

    Args:
        camera: the calibrated lens (intrinsics and distortion; its mounting is ignored).
        landmark_map: the landmarks' world positions.
        detections: per frame (t_ns, landmark ids (N,), pixels (N, 2)): identified landmarks
            and where they appeared; frames with fewer than three are skipped.
        odometry: (t_ns, v_left m/s, v_right m/s) samples, as `OdometryMeasured`.
        wheel_base_m: distance between the wheels, metres.
        config: tuning.

    Raises:
        ValueError: unknown landmark IDs (named), malformed detections, too few usable frames,
            and everything `estimate_mounting` rejects.
    """
    cfg = config or MountingConfig()
    times: list[int] = []
    poses: list[FloatArray] = []
    dropped = 0
    for k, (t_ns, ids, pixels) in enumerate(detections):
        ids_list = [int(i) for i in ids]
        px = np.asarray(pixels, dtype=np.float64).reshape(-1, 2)
        if len(px) != len(ids_list):
            raise ValueError(f"detection #{k}: {len(ids_list)} ids but {len(px)} pixels")
        unknown = [i for i in ids_list if i not in landmark_map]
        if unknown:
            raise ValueError(f"detection #{k} (t_ns {t_ns}): unknown landmark ids {unknown}")
        p_world = np.array([landmark_map.position(i) for i in ids_list]).reshape(-1, 3)
        near = poses[-1][:3, 3] if poses else None
        pose = camera_pose_from_landmarks(camera, px, p_world, near_world_m=near)
        if pose is None or pose.residual_rms_px > cfg.max_frame_rms_px:
            dropped += 1
            continue
        times.append(int(t_ns))
        poses.append(pose.T_world_camera)
    if not poses:
        raise ValueError(
            f"mounting: no usable frame among {len(detections)} (each needs three or more "
            "identified landmarks that fit one camera pose)"
        )
    heights = np.array([T[2, 3] for T in poses])
    keep = np.abs(heights - np.median(heights)) <= cfg.max_height_deviation_m
    dropped += int(np.count_nonzero(~keep))
    times = [t for t, k in zip(times, keep, strict=True) if k]
    poses = [T for T, k in zip(poses, keep, strict=True) if k]
    odo = np.asarray([(t, vl, vr) for t, vl, vr in odometry], dtype=np.float64).reshape(-1, 3)
    return estimate_mounting(
        np.array(times),
        np.array(poses),
        odo[:, 0],
        odo[:, 1],
        odo[:, 2],
        wheel_base_m=wheel_base_m,
        config=cfg,
        frames_dropped=dropped,
    )
