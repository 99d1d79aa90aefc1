"""Self-calibration on synthetic fixes with a known answer: the principal point, the first
distortion term and the mounting yaw, and what stays unobservable without motion."""

from __future__ import annotations

import math

import numpy as np

from localizer.camera import predict_pixels
from localizer.geometry import T_world_body_from_pose
from localizer.self_calibration import SelfCalibration, SelfCalibrationConfig, corrected_camera
from tests.localizer.cases import grid_positions, strong_radtan_camera

TRUE_C = np.array([0.5, -0.4, 0.04, math.radians(0.3)])  # cu, cv px; k1 relative; yaw rad
GRID = grid_positions(9, 6, 0.5, 2.5)


def _frames(poses, seed=0):
    nominal = strong_radtan_camera()
    true = corrected_camera(nominal, TRUE_C)
    rng = np.random.default_rng(seed)
    out = []
    for pose in poses:
        px, ok = predict_pixels(true, T_world_body_from_pose(*pose), GRID)
        noisy = px[ok] + rng.normal(0.0, 0.1, (int(ok.sum()), 2))
        out.append((noisy, GRID[ok], pose))
    return nominal, out


def test_drive_and_turn_recover_principal_point_distortion_and_yaw() -> None:
    straight = [(0.8 + 0.35 * k, 1.3, 0.0) for k in range(9)]
    turn = [(3.6, 1.3, k * math.pi / 5) for k in range(1, 6)]
    back = [(3.6 - 0.35 * k, 1.3, math.pi) for k in range(1, 4)]
    nominal, frames = _frames(straight + turn + back)
    cal = SelfCalibration(nominal, SelfCalibrationConfig(window_frames=40))
    rng = np.random.default_rng(1)
    for px, P, pose in frames:
        # the localizer's fix (biased by the wrong calibration) starts the adjustment
        guess = (pose[0] + rng.normal(0, 0.005), pose[1] + rng.normal(0, 0.005), pose[2] + 0.005)
        cal.add(px, P, guess, odometry=pose)
    est = cal.solve()
    assert est is not None and est.frames == 17
    assert all(est.converged), est.sigma
    np.testing.assert_allclose(est.correction[:2], TRUE_C[:2], atol=0.1)  # pixels
    assert abs(est.correction[2] - TRUE_C[2]) < 0.005  # k1 within 0.5 % of itself
    assert abs(est.correction[3] - TRUE_C[3]) < math.radians(0.03)
    fixed = cal.apply_to(nominal)
    assert abs(fixed.cu - (nominal.cu + 0.5)) < 0.1


def test_a_parked_robot_leaves_the_yaw_to_its_prior() -> None:
    nominal, frames = _frames([(1.2, 1.4, 0.3)] * 3)
    cal = SelfCalibration(nominal)
    for px, P, pose in frames:
        cal.add(px, P, pose, odometry=pose)
    est = cal.solve()
    assert est is not None
    _, _, k1_ok, yaw_ok = est.converged
    assert k1_ok and abs(est.correction[2] - TRUE_C[2]) < 0.01  # many radii in one view
    assert not yaw_ok  # a yaw only turns the heading: nothing in a parked view shows it
    assert abs(est.correction[3]) < 0.5 * est.sigma[3] + 1e-3
    assert cal.apply_to(nominal).T_body_camera[0, 1] == nominal.T_body_camera[0, 1]
