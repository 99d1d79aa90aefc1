"""Self-calibration on synthetic fixes with a known answer: the principal point, the first
distortion terms, the focal scale and the mounting yaw; what stays unobservable without
motion; and odometry's own heading drift, which must not pass for a mounting yaw."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from localizer.calibrated_camera import corrected_camera, project_with_jacobians
from localizer.camera import CameraModel, predict_pixels
from localizer.geometry import T_world_body_from_pose
from localizer.pose_tilted import rotation_world_body
from localizer.self_calibration import SelfCalibration, SelfCalibrationConfig
from localizer.types import Pose
from tests.localizer.cases import fisheye_camera, grid_positions, strong_radtan_camera

# cu, cv px; k1, k2 relative; focal relative; yaw rad
TRUE_C = np.array([0.5, -0.4, 0.04, -0.03, 0.0015, math.radians(0.3)])
GRID = grid_positions(9, 6, 0.5, 2.5)


def _frames(
    poses: list[Pose],
    true_c: np.ndarray = TRUE_C,
    seed: int = 0,
    nominal: CameraModel | None = None,
) -> tuple[CameraModel, list[tuple[np.ndarray, np.ndarray, Pose]]]:
    nominal = nominal or strong_radtan_camera()
    true = corrected_camera(nominal, true_c)
    rng = np.random.default_rng(seed)
    out = []
    for pose in poses:
        px, ok = predict_pixels(true, T_world_body_from_pose(*pose), GRID)
        noisy = px[ok] + rng.normal(0.0, 0.1, (int(ok.sum()), 2))
        out.append((noisy, GRID[ok], pose))
    return nominal, out


def _biased_odometry(poses: list[Pose], rad_per_m: float) -> list[Pose]:
    """Odometry whose heading drifts by `rad_per_m` per metre driven (unequal wheel radii),
    integrated along the true path."""
    out = [poses[0]]
    for a, b in itertools.pairwise(poses):
        c, s = math.cos(a[2]), math.sin(a[2])
        f = c * (b[0] - a[0]) + s * (b[1] - a[1])
        left = -s * (b[0] - a[0]) + c * (b[1] - a[1])
        turn = b[2] - a[2] + rad_per_m * math.hypot(f, left)
        x, y, th = out[-1]
        mid = th + 0.5 * rad_per_m * math.hypot(f, left)
        cm, sm = math.cos(mid), math.sin(mid)
        out.append((x + cm * f - sm * left, y + sm * f + cm * left, th + turn))
    return out


DRIVE = (
    [(0.8 + 0.35 * k, 1.3, 0.0) for k in range(9)]
    + [(3.6, 1.3, k * math.pi / 5) for k in range(1, 6)]
    + [(3.6 - 0.35 * k, 1.3, math.pi) for k in range(1, 4)]
)


@pytest.mark.parametrize(
    "camera", [strong_radtan_camera(), fisheye_camera()], ids=["radtan", "fisheye"]
)
def test_projection_jacobians_match_finite_differences(camera: CameraModel) -> None:
    c = np.array([0.3, -0.2, 0.02, -0.01, 0.001, 0.01])
    poses = np.array([[1.0, 1.2, 0.4], [2.0, 1.0, -2.0]])
    P = GRID[[3, 10, 20, 30, 40, 50]]
    frame = np.array([0, 0, 0, 1, 1, 1])
    px, d_c, d_pose = project_with_jacobians(camera, c, poses, P, frame)
    ref, _ = predict_pixels(corrected_camera(camera, c), T_world_body_from_pose(*poses[0]), P[:3])
    np.testing.assert_allclose(px[:3], ref, atol=1e-6)
    for k, h in enumerate((1e-4, 1e-4, 1e-6, 1e-6, 1e-7, 1e-7)):
        dc = np.zeros(6)
        dc[k] = h
        num = (project_with_jacobians(camera, c + dc, poses, P, frame)[0] - px) / h
        np.testing.assert_allclose(d_c[:, :, k], num, atol=2e-3 * max(1.0, np.abs(num).max()))
    for k in range(3):
        dp = np.zeros_like(poses)
        dp[:, k] = 1e-7
        num = (project_with_jacobians(camera, c, poses + dp, P, frame)[0] - px) / 1e-7
        np.testing.assert_allclose(d_pose[:, :, k], num, rtol=1e-3, atol=1e-2)


def test_drive_and_turn_recover_principal_point_lens_and_yaw() -> None:
    nominal, frames = _frames(DRIVE)
    cal = SelfCalibration(nominal, SelfCalibrationConfig(window_frames=40))
    rng = np.random.default_rng(1)
    odometry = _biased_odometry(DRIVE, rad_per_m=0.02)
    for (px, P, pose), odo in zip(frames, odometry, strict=True):
        # the localizer's fix (biased by the wrong calibration) starts the adjustment
        guess = (pose[0] + rng.normal(0, 0.005), pose[1] + rng.normal(0, 0.005), pose[2] + 0.005)
        cal.add(px, P, guess, odometry=odo)
    est = cal.solve()
    assert est is not None and est.frames == 17
    assert est.lens_converged and est.yaw_converged, (est.pixel_sigma_ratio, est.sigma)
    np.testing.assert_allclose(est.correction[:2], TRUE_C[:2], atol=0.1)  # pixels
    assert abs(est.correction[5] - TRUE_C[5]) < math.radians(0.03)
    # the lens as a whole: every landmark's pixel within 0.05 px of the true lens
    fixed = cal.apply_to(nominal)
    true = corrected_camera(nominal, TRUE_C)
    for pose in DRIVE[::4]:
        a, ok = predict_pixels(fixed, T_world_body_from_pose(*pose), GRID)
        b, _ = predict_pixels(true, T_world_body_from_pose(*pose), GRID)
        assert np.max(np.hypot(*(a[ok] - b[ok]).T)) < 0.05


def test_odometry_heading_drift_does_not_pass_for_a_mounting_yaw() -> None:
    no_yaw = TRUE_C.copy()
    no_yaw[5] = 0.0
    nominal, frames = _frames(DRIVE, no_yaw)
    cal = SelfCalibration(nominal, SelfCalibrationConfig(window_frames=40))
    for (px, P, pose), odo in zip(frames, _biased_odometry(DRIVE, 0.03), strict=True):
        cal.add(px, P, pose, odometry=odo)
    est = cal.solve()
    assert est is not None
    assert abs(est.correction[5]) < math.radians(0.02), math.degrees(est.correction[5])


def test_a_parked_robot_leaves_the_yaw_to_its_prior() -> None:
    nominal, frames = _frames([(1.2, 1.4, 0.3)] * 3)
    cal = SelfCalibration(nominal)
    for px, P, pose in frames:
        cal.add(px, P, pose, odometry=pose)
    est = cal.solve()
    assert est is not None
    # many radii in one view pin the radial terms, but not the centre, which parked looks
    # like a translation of the body: the lens block is not applied
    assert est.pixel_sigma_ratio < 0.1 and est.sigma[0] > 0.25 and not est.lens_converged
    assert not est.yaw_converged  # a yaw only turns the heading: nothing parked shows it
    assert abs(est.correction[5]) < 0.5 * est.sigma[5] + 1e-3
    assert cal.apply_to(nominal).T_body_camera[0, 1] == nominal.T_body_camera[0, 1]


def test_three_landmarks_at_one_radius_leave_the_lens_to_its_prior() -> None:
    nominal = strong_radtan_camera()
    cal = SelfCalibration(nominal)
    cluster = np.array([[1.2, 1.4, 2.5], [1.5, 1.4, 2.5], [1.35, 1.6, 2.5]])
    true = corrected_camera(nominal, TRUE_C)
    for pose in [(1.35, 1.45, 0.0)] * 3:
        px, ok = predict_pixels(true, T_world_body_from_pose(*pose), cluster)
        cal.add(px[ok], cluster[ok], pose, odometry=pose)
    est = cal.solve()
    assert est is not None and not est.lens_converged
    assert cal.apply_to(nominal).cu == nominal.cu


def test_config_rejects_a_prior_of_the_wrong_length() -> None:
    with pytest.raises(ValueError, match="prior_sigma"):
        SelfCalibrationConfig(prior_sigma=(1.0, 1.0, 0.1, 0.02))  # type: ignore[arg-type]


def _tilted_frames(
    poses: list[Pose], floors: list[tuple[float, float, float]], true_c: np.ndarray
) -> tuple[CameraModel, list[tuple[np.ndarray, np.ndarray, Pose]]]:
    """Like `_frames`, the body on a tilted, raised floor (roll, pitch, dz) per frame."""
    nominal = strong_radtan_camera()
    true = corrected_camera(nominal, true_c)
    rng = np.random.default_rng(3)
    out = []
    for pose, (r, p, dz) in zip(poses, floors, strict=True):
        T = T_world_body_from_pose(*pose)
        T[:3, :3] = rotation_world_body(pose[2], r, p)
        T[2, 3] = dz
        px, ok = predict_pixels(true, T, GRID)
        out.append((px[ok] + rng.normal(0.0, 0.1, (int(ok.sum()), 2)), GRID[ok], pose))
    return nominal, out


def test_projection_on_a_tilted_floor_matches_the_camera_and_its_pose_derivatives() -> None:
    camera = fisheye_camera()
    c = np.array([0.3, -0.2, 0.02, -0.01, 0.001, 0.01])
    poses = np.array([[1.0, 1.2, 0.4], [2.0, 1.0, -2.0]])
    floors = np.array([[0.012, -0.017, 0.03], [-0.02, 0.005, -0.04]])
    P = GRID[[3, 10, 20, 30, 40, 50]]
    frame = np.array([0, 0, 0, 1, 1, 1])
    px, _, d_pose = project_with_jacobians(camera, c, poses, P, frame, floors)
    T = T_world_body_from_pose(*poses[1])
    T[:3, :3] = rotation_world_body(poses[1][2], *floors[1][:2])
    T[2, 3] = floors[1][2]
    ref, _ = predict_pixels(corrected_camera(camera, c), T, P[3:])
    np.testing.assert_allclose(px[3:], ref, atol=1e-6)
    for k in range(3):
        dp = np.zeros_like(poses)
        dp[:, k] = 1e-7
        num = (project_with_jacobians(camera, c, poses + dp, P, frame, floors)[0] - px) / 1e-7
        np.testing.assert_allclose(d_pose[:, :, k], num, rtol=1e-3, atol=1e-2)


def test_a_floor_tilt_given_with_the_fixes_is_not_taken_for_a_principal_point_shift() -> None:
    # driving and turning on a floor 1 deg out of level (rising along +x), 3 cm high at x = 2
    g = math.tan(math.radians(1.0))
    floors = []
    for x, _, th in DRIVE:
        roll, pitch = math.atan(-math.sin(th) * g), -math.atan(math.cos(th) * g)
        floors.append((roll, pitch, 0.03 + g * (x - 2.0)))
    true_c = np.array([0.3, -0.3, 0.0, 0.0, 0.0, 0.0])
    nominal, frames = _tilted_frames(DRIVE, floors, true_c)
    config = SelfCalibrationConfig(window_frames=40)
    given, level = SelfCalibration(nominal, config), SelfCalibration(nominal, config)
    for (px, P, pose), fl in zip(frames, floors, strict=True):
        given.add(px, P, pose, odometry=pose, floor=fl)
        level.add(px, P, pose, odometry=pose)
    est, est_level = given.solve(), level.solve()
    assert est is not None and est_level is not None
    np.testing.assert_allclose(est.correction[:2], true_c[:2], atol=0.1)  # pixels
    # without the floor the same fixes read part of the tilt into the centre (0.44 px here)
    assert np.max(np.abs(est_level.correction[:2] - true_c[:2])) > 0.3
