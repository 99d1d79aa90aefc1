from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from localizer.camera import CameraModel, T_body_camera_upward, predict_pixels
from localizer.geometry import T_world_body_from_pose, wrap_angle
from localizer.pose import PoseFix, solve_pose
from localizer.pose_config import PoseSolveConfig
from localizer.pose_paper import (
    heading_from_paper_angle,
    pixels_from_pose_paper,
    pose_from_landmark_pair,
)
from localizer.pose_tilted import rotation_world_body
from tests.localizer.cameras import LENSES, MOUNTINGS, make_camera

# Four landmarks at different heights around the robot's position (1.5, 2.3).
LANDMARKS = np.array([[1.0, 2.0, 2.5], [2.2, 2.0, 2.62], [1.6, 3.0, 2.45], [2.0, 1.6, 2.55]])
HEADINGS = [0.3, -1.9, math.pi, math.pi - 1e-4, -math.pi + 1e-4]
TILT = PoseSolveConfig(estimate_tilt=True)  # a tilt taken when the spots demand it
ALWAYS_TILT = PoseSolveConfig(estimate_tilt=True, tilt_min_chi2_drop=0.0)


def observe(
    cam: CameraModel, pose: tuple[float, float, float], P: np.ndarray, tilt=(0.0, 0.0)
) -> np.ndarray:
    T = T_world_body_from_pose(*pose)
    T[:3, :3] = rotation_world_body(pose[2], *tilt)
    px, valid = predict_pixels(cam, T, P)
    assert valid.all(), "test geometry puts a landmark out of view"
    return px


def assert_pose(fix: PoseFix | None, pose: tuple[float, float, float], atol: float) -> None:
    assert fix is not None
    np.testing.assert_allclose([fix.x, fix.y], pose[:2], atol=atol)
    assert abs(wrap_angle(fix.theta - pose[2])) < atol
    assert -math.pi < fix.theta <= math.pi


# --- the paper's closed form (eqs. 1-3) ------------------------------------------------------


@pytest.mark.parametrize("heading", HEADINGS)
@pytest.mark.parametrize("yaw", [0.0, 0.7, -math.pi / 2])
def test_paper_closed_form_is_exact_for_an_ideal_camera_on_the_axle(
    heading: float, yaw: float
) -> None:
    model, dist = LENSES["pinhole"]
    cam = CameraModel(640, 480, 300.0, 300.0, 320.0, 240.0, model, np.array(dist),
                      T_body_camera_upward(yaw=yaw))  # fmt: skip
    P = LANDMARKS[:2].copy()
    P[:, 2] = 2.5
    px = observe(cam, (1.5, 2.3, heading), P)
    rx, ry, theta_paper = pose_from_landmark_pair(px[0], px[1], P[0], P[1], (cam.cu, cam.cv))
    np.testing.assert_allclose([rx, ry], [1.5, 2.3], atol=1e-9)
    assert heading_from_paper_angle(theta_paper, yaw) == pytest.approx(
        float(wrap_angle(heading)), abs=1e-9
    ) or abs(heading_from_paper_angle(theta_paper, yaw) - float(wrap_angle(heading))) == (
        pytest.approx(2 * math.pi, abs=1e-9)
    )
    # The scale is D / d (eq. 2), metres per pixel: (ceiling - camera height) / f.
    d = np.linalg.norm(px[1] - px[0])
    assert np.linalg.norm(P[1, :2] - P[0, :2]) / d == pytest.approx((2.5 - 0.3) / 300.0)


def test_paper_heading_is_measured_from_the_world_y_axis_for_an_upright_image() -> None:
    # Robot facing world +y (REP-103 heading pi/2): the paper's theta is pi (yaw-0 mounting,
    # image "up" = robot forward, and the image's up is (0, -1) in OpenCV pixels).
    assert heading_from_paper_angle(math.pi) == pytest.approx(math.pi / 2)
    assert heading_from_paper_angle(math.pi / 2) == pytest.approx(0.0)


def test_corrected_eq_3_inverts_eq_2_and_matches_predict_pixels() -> None:
    model, dist = LENSES["pinhole"]
    cam = CameraModel(640, 480, 300.0, 300.0, 320.0, 240.0, model, np.array(dist),
                      T_body_camera_upward())  # fmt: skip
    P = LANDMARKS.copy()
    P[:, 2] = 2.5
    pose = (1.5, 2.3, 2.0)
    px = observe(cam, pose, P)
    rx, ry, th = pose_from_landmark_pair(px[0], px[1], P[0], P[1], (320.0, 240.0))
    s = np.linalg.norm(P[1, :2] - P[0, :2]) / np.linalg.norm(px[1] - px[0])
    np.testing.assert_allclose(pixels_from_pose_paper((rx, ry), th, s, (320, 240), P), px,
                               atol=1e-9)  # fmt: skip


def test_paper_closed_form_rejects_coincident_landmarks() -> None:
    with pytest.raises(ValueError, match="coincide"):
        pose_from_landmark_pair((10, 10), (10, 10), (0, 0), (1, 0), (320, 240))


# --- the tilt model -------------------------------------------------------------------------


def test_rotation_world_body_is_yaw_pitch_roll() -> None:
    R = rotation_world_body(0.3, 0.02, -0.05)
    cz, sz = math.cos(0.3), math.sin(0.3)
    Rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    Ry = np.array(
        [[math.cos(-0.05), 0, math.sin(-0.05)], [0, 1, 0], [-math.sin(-0.05), 0, math.cos(-0.05)]]
    )
    Rx = np.array(
        [[1, 0, 0], [0, math.cos(0.02), -math.sin(0.02)], [0, math.sin(0.02), math.cos(0.02)]]
    )
    np.testing.assert_allclose(R, Rz @ Ry @ Rx, atol=1e-15)


# --- the production solver: exact recovery ---------------------------------------------------


@pytest.mark.parametrize("lens", ["radial-tangential", "equidistant"])
@pytest.mark.parametrize("mounting", list(MOUNTINGS))
@pytest.mark.parametrize("heading", HEADINGS)
@pytest.mark.parametrize("n", [2, 3, 4])
def test_solve_pose_recovers_the_pose_exactly(
    lens: str, mounting: str, heading: float, n: int
) -> None:
    cam = make_camera(lens, mounting)
    pose = (1.5, 2.3, heading)
    px = observe(cam, pose, LANDMARKS[:n])
    fix = solve_pose(cam, px, LANDMARKS[:n], landmark_ids=tuple(range(10, 10 + n)))
    assert_pose(fix, pose, 1e-8)
    assert fix is not None
    assert fix.residual_rms_px < 1e-6
    assert fix.landmark_ids == tuple(range(10, 10 + n))
    assert fix.n_landmarks == n
    np.testing.assert_array_equal(fix.tilt, [0.0, 0.0])
    assert fix.covariance.shape == (3, 3)
    np.testing.assert_allclose(fix.covariance, fix.covariance.T)
    assert np.all(np.linalg.eigvalsh(fix.covariance) > 0)


@pytest.mark.parametrize("start", ["tuple", "fix"])
def test_solve_pose_from_an_initial_guess(start: str) -> None:
    cam = make_camera("equidistant", "offset-yaw90")
    pose = (1.5, 2.3, -math.pi + 1e-3)
    px = observe(cam, pose, LANDMARKS[:3])
    guess = (1.45, 2.4, math.pi - 0.1)  # across the +-pi cut
    initial = guess if start == "tuple" else PoseFix(*guess, covariance=np.eye(3))
    assert_pose(solve_pose(cam, px, LANDMARKS[:3], initial=initial), pose, 1e-8)


@pytest.mark.parametrize("lens", ["radial-tangential", "equidistant"])
@pytest.mark.parametrize("n", [3, 4])
def test_solve_pose_estimates_the_body_tilt(lens: str, n: int) -> None:
    cam = make_camera(lens, "offset-yaw90")
    pose, tilt = (1.5, 2.3, 2.5), (0.03, -0.04)  # ~2 deg: a floor bump
    px = observe(cam, pose, LANDMARKS[:n], tilt)
    fix = solve_pose(cam, px, LANDMARKS[:n], config=ALWAYS_TILT)
    assert_pose(fix, pose, 1e-5)  # the solver stops at 1 % of a standard deviation
    assert fix is not None
    np.testing.assert_allclose(fix.tilt, tilt, atol=1e-6)  # stops at 1 % of a sigma
    # Ignoring the tilt shifts the position by about (ceiling height) x (tilt).
    level = solve_pose(cam, px, LANDMARKS[:n])
    assert level is not None
    assert math.hypot(level.x - pose[0], level.y - pose[1]) > 0.05
    assert level.residual_rms_px > fix.residual_rms_px


def test_tilt_needs_three_landmarks_and_a_prior_pulls_it_to_zero() -> None:
    cam = make_camera()
    pose = (1.5, 2.3, 0.3)
    px = observe(cam, pose, LANDMARKS[:2])
    fix = solve_pose(cam, px, LANDMARKS[:2], config=TILT)
    assert fix is not None
    np.testing.assert_array_equal(fix.tilt, [0.0, 0.0])
    px4 = observe(cam, pose, LANDMARKS, (0.02, 0.0))
    free = solve_pose(cam, px4, LANDMARKS, config=ALWAYS_TILT)
    tight = solve_pose(cam, px4, LANDMARKS, config=replace(ALWAYS_TILT, tilt_sigma_rad=1e-4))
    assert free is not None and tight is not None
    assert abs(tight.tilt[0]) < 0.5 * abs(free.tilt[0])


def test_tilt_is_used_only_when_the_spots_demand_it() -> None:
    rng = np.random.default_rng(3)
    cam = make_camera("equidistant", "upward")
    pose = (1.5, 2.3, 1.0)
    level_px = observe(cam, pose, LANDMARKS)
    tilted_px = observe(cam, pose, LANDMARKS, (0.06, -0.05))  # a 4.5 deg floor bump
    flat_tilted, bump_err, bump_level_err = 0, [], []
    for _ in range(40):
        noise = rng.normal(0, 0.3, level_px.shape)
        flat = solve_pose(cam, level_px + noise, LANDMARKS, config=TILT)
        assert flat is not None
        flat_tilted += bool(np.any(flat.tilt != 0.0))
        bump = solve_pose(cam, tilted_px + noise, LANDMARKS, config=TILT)
        level = solve_pose(cam, tilted_px + noise, LANDMARKS)
        assert bump is not None and level is not None
        bump_err.append(math.hypot(bump.x - pose[0], bump.y - pose[1]))
        bump_level_err.append(math.hypot(level.x - pose[0], level.y - pose[1]))
    assert flat_tilted <= 4  # ~1 % false alarms expected; a level floor stays level
    assert np.mean(bump_level_err) > 0.15  # ignoring the bump: the paper's 17 cm kind of error
    assert np.mean(bump_err) < 0.5 * np.mean(bump_level_err)


# --- statistics ------------------------------------------------------------------------------


@pytest.mark.parametrize(("n", "tilt"), [(2, False), (4, False), (4, True)])
def test_covariance_matches_monte_carlo_scatter(n: int, tilt: bool) -> None:
    rng = np.random.default_rng(7)
    cam = make_camera("equidistant", "offset-yaw90")
    pose = (1.5, 2.3, 1.0)
    px = observe(cam, pose, LANDMARKS[:n])
    errors = []
    for _ in range(300):
        noisy = px + rng.normal(0, 0.3, px.shape)
        fix = solve_pose(
            cam,
            noisy,
            LANDMARKS[:n],
            config=PoseSolveConfig(estimate_tilt=tilt, tilt_min_chi2_drop=0.0),
        )
        assert fix is not None
        errors.append([fix.x - pose[0], fix.y - pose[1], wrap_angle(fix.theta - pose[2])])
    reported = solve_pose(
        cam, px, LANDMARKS[:n], config=PoseSolveConfig(estimate_tilt=tilt, tilt_min_chi2_drop=0.0)
    )
    assert reported is not None
    ratio = np.std(errors, axis=0) / np.sqrt(np.diag(reported.covariance))
    assert np.all((ratio > 1 / 1.5) & (ratio < 1.5)), ratio


def test_accuracy_under_pixel_noise_at_a_2_5_m_ceiling() -> None:
    rng = np.random.default_rng(11)
    cam = make_camera("radial-tangential", "upward")
    P = LANDMARKS[:2].copy()
    P[:, 2] = 2.5
    pos_err, head_err, rms = [], [], []
    for heading in np.linspace(-math.pi, math.pi, 40, endpoint=False):
        pose = (1.6, 2.0, float(heading))
        px = observe(cam, pose, P)
        fix = solve_pose(cam, px + rng.normal(0, 0.3, px.shape), P)
        assert fix is not None
        pos_err.append(math.hypot(fix.x - pose[0], fix.y - pose[1]))
        head_err.append(abs(wrap_angle(fix.theta - pose[2])))
        rms.append(fix.residual_rms_px)
    assert np.mean(pos_err) < 0.003  # metres: well under 1 cm
    assert np.degrees(np.mean(head_err)) < 0.3
    assert 0.02 < np.mean(rms) < 0.6


# --- degenerate and bad input ----------------------------------------------------------------


def test_degenerate_inputs_give_none() -> None:
    cam = make_camera()
    px = observe(cam, (1.5, 2.3, 0.3), LANDMARKS)
    assert solve_pose(cam, px[:1], LANDMARKS[:1]) is None
    assert solve_pose(cam, np.zeros((0, 2)), np.zeros((0, 3))) is None
    same = np.vstack([px[0], px[0] + 0.5])
    assert solve_pose(cam, same, LANDMARKS[:2]) is None  # coincident in the image
    twin = np.vstack([LANDMARKS[0], LANDMARKS[0]])
    assert solve_pose(cam, px[:2], twin) is None  # coincident in the world
    low = LANDMARKS[:2].copy()
    low[0, 2] = 0.2  # below the camera
    assert solve_pose(cam, px[:2], low) is None
    bad = px[:2].copy()
    bad[0, 0] = np.nan
    assert solve_pose(cam, bad, LANDMARKS[:2]) is None


def test_mismatched_shapes_raise() -> None:
    cam = make_camera()
    with pytest.raises(ValueError, match="p_world"):
        solve_pose(cam, np.zeros((3, 2)), np.zeros((2, 3)))
    with pytest.raises(ValueError, match="pixels"):
        solve_pose(cam, np.zeros(4), np.zeros((2, 3)))


def test_nested_lists_give_the_same_fix_as_arrays_and_are_checked_alike() -> None:
    # the tracker passes lists (no round trip through numpy): the same numbers, bit for bit
    cam = make_camera()
    pose = (1.5, 2.3, 0.3)
    px = observe(cam, pose, LANDMARKS) + np.array([[0.3, -0.2], [-0.1, 0.4], [0.2, 0.1], [0, 0]])
    kw = {"initial": (1.49, 2.31, 0.31), "pixel_sigma_px": [0.3, 0.25, 0.4, 0.3],
          "config": PoseSolveConfig(loss="huber", estimate_tilt=True)}  # fmt: skip
    a = solve_pose(cam, px, LANDMARKS, **kw)
    b = solve_pose(cam, px.tolist(), LANDMARKS.tolist(), **kw)
    assert a is not None and b is not None
    assert (a.x, a.y, a.theta, a.residuals_px) == (b.x, b.y, b.theta, b.residuals_px)
    assert np.array_equal(a.covariance, b.covariance)
    with pytest.raises(ValueError, match="p_world"):
        solve_pose(cam, px.tolist(), LANDMARKS[:3].tolist())
    with pytest.raises(ValueError, match="pixels"):
        solve_pose(cam, [[1.0, 2.0, 3.0]] * 4, LANDMARKS.tolist())


def test_a_fix_plus_a_covariance_turned_about_the_vertical() -> None:
    rng = np.random.default_rng(7)
    A = rng.normal(size=(3, 3))
    B = rng.normal(size=(3, 3))
    base, term = A @ A.T, B @ B.T
    fix = PoseFix(1.0, 2.0, 0.5, base, landmark_ids=(4, 5), n_landmarks=2, residuals_px=(0.1, 0.2))
    turn = 0.37
    c, s = math.cos(turn), math.sin(turn)
    R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    out = fix.plus_covariance_turned(term, turn)
    np.testing.assert_allclose(out.covariance, base + R @ term @ R.T, rtol=1e-13, atol=1e-13)
    assert (out.x, out.y, out.theta, out.landmark_ids, out.residuals_px) == (
        1.0, 2.0, 0.5, (4, 5), (0.1, 0.2),
    )  # fmt: skip
    np.testing.assert_array_equal(fix.covariance, base)  # the fix itself unchanged
