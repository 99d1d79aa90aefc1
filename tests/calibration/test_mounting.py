"""Mounting calibration on simulated observations: a turn in place and a straight line under
known landmarks, pixels from `predict_pixels` plus 0.3 px noise."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pytest

from calibration.mounting import (
    MountingConfig,
    camera_yaw,
    estimate_mounting,
    mounting_from_observations,
)
from localizer.camera import T_body_camera_upward, predict_pixels
from localizer.geometry import T_world_body_from_pose
from localizer.landmark_map import LandmarkMap
from sim.cameras import wide_angle_camera

WHEEL_BASE = 0.4


def _landmarks(rng: np.random.Generator) -> LandmarkMap:
    xs, ys = np.meshgrid(np.arange(-1.0, 4.01, 1.0), np.arange(-1.5, 3.51, 1.0))
    z = 2.5 + rng.uniform(-0.15, 0.15, xs.size)  # ceilings are not flat
    return LandmarkMap(
        ids=np.arange(xs.size) + 10, positions=np.column_stack([xs.ravel(), ys.ravel(), z])
    )


def _drive(
    turn_rad: float = 1.5 * math.pi, straight_m: float = 1.5, speed: float = 0.3
) -> tuple[list[tuple[int, float, float]], Callable[[float], tuple[float, float, float]], float]:
    """Wheel speeds (50 Hz), the true body pose as a function of time, and the duration.

    Turn in place at 0.6 rad/s (left for a positive `turn_rad`), stop for 1 s, drive
    straight (backwards for a negative `speed`), stop for 1 s.
    """
    x0, y0, th0 = 1.2, 0.8, 0.3
    omega = math.copysign(0.6, turn_rad)
    t_turn = turn_rad / omega
    t_straight0 = t_turn + 1.0
    t_end = t_straight0 + straight_m / abs(speed)

    def pose(t: float) -> tuple[float, float, float]:
        if t <= t_turn:
            return x0, y0, th0 + omega * t
        th = th0 + turn_rad
        d = speed * min(max(t - t_straight0, 0.0), t_end - t_straight0)
        return x0 + d * math.cos(th), y0 + d * math.sin(th), th

    def wheels(t: float) -> tuple[float, float]:
        if t < t_turn:
            return -omega * WHEEL_BASE / 2, omega * WHEEL_BASE / 2
        if t_straight0 <= t < t_end:
            return speed, speed
        return 0.0, 0.0

    odo = [(round(t * 1e9), *wheels(t)) for t in np.arange(0.0, t_end + 1.0, 0.02)]
    return odo, pose, t_end + 1.0


def _exact_poses(T_body_camera: np.ndarray, **drive: float):
    """Frame times (10 Hz), exact camera poses and odometry arrays."""
    odo, pose, t_end = _drive(**drive)
    times = np.arange(0.0, t_end, 0.1)
    T_wc = np.array([T_world_body_from_pose(*pose(t)) @ T_body_camera for t in times])
    odo_t, vl, vr = np.array(odo).T
    return np.round(times * 1e9).astype(np.int64), T_wc, odo_t, vl, vr


def _observations(camera, landmarks, pose, t_end, rng, *, noise_px=0.3):
    detections = []
    for t in np.arange(0.0, t_end, 0.1):
        px, valid = predict_pixels(camera, T_world_body_from_pose(*pose(t)), landmarks.positions)
        px = px[valid] + rng.normal(0.0, noise_px, (int(valid.sum()), 2))
        detections.append((int(t * 1e9), landmarks.ids[valid].tolist(), px))
    return detections


@pytest.mark.parametrize("lens", ["fisheye", "pinhole"])
def test_recovers_a_camera_10cm_off_the_axle_yawed_90_deg(lens: str) -> None:
    rng = np.random.default_rng(11)
    offset = (0.06, -0.08)  # 10 cm from the axle midpoint
    T_true = T_body_camera_upward(yaw=math.pi / 2, offset_xy=offset, height=0.32)
    camera = wide_angle_camera(lens, T_body_camera=T_true)  # type: ignore[arg-type]
    landmarks = _landmarks(rng)
    odo, pose, t_end = _drive()
    detections = _observations(camera, landmarks, pose, t_end, rng)
    assert min(len(d[1]) for d in detections) >= 4

    lens_only = wide_angle_camera(lens)  # type: ignore[arg-type]  # mounting unknown
    result = mounting_from_observations(
        lens_only, landmarks, detections, odo, wheel_base_m=WHEEL_BASE
    )
    assert abs(math.degrees(result.yaw_rad) - 90.0) < 0.2
    np.testing.assert_allclose(result.offset_xy_m, offset, atol=0.005)
    np.testing.assert_allclose(result.height_m, 0.32, atol=0.005)
    np.testing.assert_allclose(result.T_body_camera[:3, :3], T_true[:3, :3], atol=0.005)
    np.testing.assert_allclose(result.turn_centre_world, [1.2, 0.8], atol=0.005)
    # the stated uncertainty is honest and small
    assert result.yaw_std_rad < math.radians(0.1)
    assert np.all(result.offset_std_m < 0.003)
    assert np.all(np.abs(result.offset_xy_m - offset) < 4 * result.offset_std_m + 1e-3)
    assert np.sqrt(np.mean(result.circle_residuals_m**2)) < 0.005
    np.testing.assert_allclose(
        result.turn_angle_camera_rad, result.turn_angle_odometry_rad, atol=0.05
    )
    assert result.frames_turn > 50 and result.frames_straight > 30 and result.frames_dropped == 0
    assert result.to_dict()["yaw_deg"] == pytest.approx(90.0, abs=0.2)


def test_exact_poses_give_the_exact_mounting() -> None:
    T_true = T_body_camera_upward(
        yaw=-2.0, offset_xy=(-0.12, 0.03), height=0.25, tilt_xy=(0.01, -0.02)
    )
    # a right turn, then reversing
    t_ns, T_wc, odo_t, vl, vr = _exact_poses(T_true, turn_rad=-math.pi, straight_m=0.8, speed=-0.3)
    result = estimate_mounting(t_ns, T_wc, odo_t, vl, vr, wheel_base_m=WHEEL_BASE)
    np.testing.assert_allclose(result.T_body_camera, T_true, atol=1e-6)
    # with a tilt, the yaw is that of the tilted axes: camera_yaw of the mounting itself
    np.testing.assert_allclose(result.yaw_rad, camera_yaw(T_true[None])[0], atol=1e-9)
    np.testing.assert_allclose(result.yaw_rad, -2.0, atol=1e-3)
    # from the first to the last turning frame (t = 0 ... 5.2 s at 0.6 rad/s)
    np.testing.assert_allclose(result.turn_angle_camera_rad, -0.6 * 5.2, atol=1e-6)
    np.testing.assert_allclose(result.turn_angle_odometry_rad, -0.6 * 5.2, atol=0.01)


def test_insufficient_or_bad_data_is_rejected() -> None:
    T_true = T_body_camera_upward(yaw=0.3, offset_xy=(0.1, 0.0))
    args = _exact_poses(T_true, turn_rad=0.5, straight_m=1.0)
    with pytest.raises(
        ValueError, match=r"turn in place through at least 90 deg.*sweeping 2\d deg"
    ):
        estimate_mounting(*args, wheel_base_m=WHEEL_BASE)
    args = _exact_poses(T_true, straight_m=0.1)
    with pytest.raises(ValueError, match=r"drive straight for at least 0.3 m"):
        estimate_mounting(*args, wheel_base_m=WHEEL_BASE)
    # a "turn" that was really an arc: the camera centres do not lie on one circle
    t_ns, T_wc, odo_t, vl, vr = _exact_poses(T_true)
    T_wc[:, 0, 3] += 0.05e-9 * t_ns
    with pytest.raises(ValueError, match=r"off one circle: the robot must turn in place"):
        estimate_mounting(t_ns, T_wc, odo_t, vl, vr, wheel_base_m=WHEEL_BASE)
    with pytest.raises(ValueError, match="frame times but"):
        estimate_mounting(t_ns[:-1], T_wc, odo_t, vl, vr, wheel_base_m=WHEEL_BASE)
    with pytest.raises(ValueError, match="odometry times must increase"):
        estimate_mounting(t_ns, T_wc, odo_t[::-1], vl, vr, wheel_base_m=WHEEL_BASE)
    with pytest.raises(ValueError, match="wheel base must be positive"):
        estimate_mounting(t_ns, T_wc, odo_t, vl, vr, wheel_base_m=0.0)


def test_observations_with_unknown_or_too_few_landmarks_are_rejected() -> None:
    rng = np.random.default_rng(2)
    landmarks = _landmarks(rng)
    camera = wide_angle_camera("fisheye")
    with pytest.raises(ValueError, match=r"detection #0 \(t_ns 5\): unknown landmark ids \[999\]"):
        mounting_from_observations(
            camera, landmarks, [(5, [10, 999], np.zeros((2, 2)))], [], wheel_base_m=WHEEL_BASE
        )
    with pytest.raises(ValueError, match="no usable frame among 1"):
        mounting_from_observations(
            camera, landmarks, [(5, [10, 11], np.zeros((2, 2)))], [], wheel_base_m=WHEEL_BASE
        )
    with pytest.raises(ValueError, match="2 ids but 3 pixels"):
        mounting_from_observations(
            camera, landmarks, [(5, [10, 11], np.zeros((3, 2)))], [], wheel_base_m=WHEEL_BASE
        )
    assert isinstance(MountingConfig().min_turn_angle_rad, float)


def test_frames_off_the_cameras_height_are_dropped() -> None:
    """Frames whose camera pose is far off the camera's height (what a wrong P3P branch or a
    misidentification gives) are dropped, and the mounting is that of the good frames."""
    rng = np.random.default_rng(5)
    T_true = T_body_camera_upward(yaw=0.3, offset_xy=(0.05, 0.02), height=0.3)
    camera = wide_angle_camera("fisheye", T_body_camera=T_true)
    raised = wide_angle_camera("fisheye", T_body_camera=T_body_camera_upward(height=0.45))
    landmarks = _landmarks(rng)
    odo, pose, t_end = _drive()
    detections = _observations(camera, landmarks, pose, t_end, rng)
    lens = wide_angle_camera("fisheye")
    clean = mounting_from_observations(lens, landmarks, detections, odo, wheel_base_m=WHEEL_BASE)
    wrong = _observations(raised, landmarks, pose, t_end, rng)
    bad = list(range(5, len(detections), 9))
    for k in bad:
        detections[k] = wrong[k]
    result = mounting_from_observations(lens, landmarks, detections, odo, wheel_base_m=WHEEL_BASE)
    # every raised frame dropped (one may be among those the clean run drops anyway)
    assert len(bad) <= result.frames_dropped <= clean.frames_dropped + len(bad)
    assert abs(result.yaw_rad - 0.3) < math.radians(0.2)
    np.testing.assert_allclose(result.offset_xy_m, (0.05, 0.02), atol=0.005)
    loose = MountingConfig(max_height_deviation_m=1.0)  # without the check they spoil it
    spoilt = mounting_from_observations(
        lens, landmarks, detections, odo, wheel_base_m=WHEEL_BASE, config=loose
    )
    assert spoilt.frames_dropped <= clean.frames_dropped
    assert np.linalg.norm(spoilt.offset_xy_m - (0.05, 0.02)) > 0.005
