"""The carried floor (`floor_plane`) and the fix solved with it as its prior (`solve_pose(...,
floor_prior=...)`): known answers from synthetic spots."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from localizer.calibration_consider import CalibrationConsider
from localizer.camera import CameraModel, normalized_from_pixels, predict_pixels
from localizer.floor_plane import (
    FloorPlane,
    FloorPlaneConfig,
    body_tilt,
    conditioned,
    fused,
    fused_sensitivity,
    state_map,
    tilt_map,
    world_gradient,
)
from localizer.geometry import T_world_body_from_pose
from localizer.noise_model import PixelNoiseConfig, PixelNoiseModel
from localizer.pose import solve_pose
from localizer.pose_config import PoseSolveConfig
from localizer.pose_tilted import floor_change_chi2, rotation_world_body, solve_tilted
from localizer.tracking import scale_px_per_m
from tests.localizer.cameras import make_camera
from tests.localizer.cases import (
    fisheye_camera,
    grid_positions,
    miscalibrated,
    strong_radtan_camera,
)

CFG = FloorPlaneConfig()
TILT = PoseSolveConfig(estimate_tilt=True)  # a tilt taken when the spots demand it
ALWAYS_TILT = PoseSolveConfig(estimate_tilt=True, tilt_min_chi2_drop=0.0)
# a 4 x 4 grid 0.8 m apart at about 2.5 m (uneven), around (2, 2)
GRID = np.array(
    [[0.8 + 0.8 * i, 0.8 + 0.8 * j, 2.5 + 0.03 * ((i * 3 + j) % 4 - 1.5)]
     for i in range(4) for j in range(4)]
)  # fmt: skip


def observe(
    cam: CameraModel,
    pose: tuple[float, float, float],
    P: np.ndarray,
    tilt: tuple[float, float] = (0.0, 0.0),
    dz: float = 0.0,
) -> np.ndarray:
    """Pixels of P from a body at `pose` tilted (roll, pitch) and raised by dz."""
    T = T_world_body_from_pose(*pose)
    T[:3, :3] = rotation_world_body(pose[2], *tilt)
    T[2, 3] = dz
    px, valid = predict_pixels(cam, T, P)
    assert valid.all(), "test geometry puts a landmark out of view"
    return px


def on_plane(h0: float, g: np.ndarray, x: float, y: float, theta: float):
    """The tilt and height of a body at (x, y, theta) on the floor h = h0 + g . (x, y)."""
    return body_tilt(g, theta), h0 + float(g @ [x, y])


@pytest.mark.parametrize("theta", [0.0, 0.9, -2.4, math.pi])
def test_a_body_tilted_by_the_floor_has_its_axes_in_the_floor(theta: float) -> None:
    g = np.array([0.017, -0.012])  # about 1 deg and 0.7 deg
    roll, pitch = body_tilt(g, theta)
    R = rotation_world_body(theta, roll, pitch)
    normal = np.array([-g[0], -g[1], 1.0])
    for axis in (R[:, 0], R[:, 1]):  # forward and left lie in the floor (to second order)
        assert abs(axis @ normal) < 1e-3 * np.linalg.norm(normal)
    np.testing.assert_allclose(world_gradient(roll, pitch, theta), g, atol=1e-12)
    # eq. (2): the first-order map is orthogonal and agrees with eq. (1)
    M = tilt_map(theta)
    np.testing.assert_allclose(M @ M.T, np.eye(2), atol=1e-12)
    np.testing.assert_allclose(M @ g, (roll, pitch), atol=1e-5)
    B = state_map(theta)
    np.testing.assert_allclose(B @ B.T, np.eye(3), atol=1e-12)


@pytest.mark.parametrize("lens", ["equidistant", "radial-tangential"])
def test_the_fix_recovers_tilt_and_height_from_spots(lens: str) -> None:
    cam = make_camera(lens, "offset-tilted")
    pose, tilt, dz = (2.1, 1.9, 0.4), (0.015, -0.02), 0.045  # ~1 deg, a floor 4.5 cm high
    px = observe(cam, pose, GRID, tilt, dz)
    prior = FloorPlane.level(CFG).prior(pose, CFG)
    # noise-free spots at a 0.01 px sigma: the prior's pull is negligible
    fix = solve_pose(cam, px, GRID, initial=(2.0, 2.0, 0.35), config=TILT,
                     pixel_sigma_px=0.01, floor_prior=prior)  # fmt: skip
    assert fix is not None and fix.floor is not None and fix.floor_covariance is not None
    np.testing.assert_allclose([fix.x, fix.y, fix.theta], pose, atol=1e-5)
    np.testing.assert_allclose(fix.floor, (*tilt, dz), atol=1e-5)
    np.testing.assert_allclose(fix.residuals_px, 0.0, atol=1e-3)
    # the level fit (the map's floor, no tilt) is off by about ceiling x tilt
    level = solve_pose(cam, px, GRID, initial=pose)
    assert level is not None
    assert math.hypot(level.x - pose[0], level.y - pose[1]) > 0.02
    # the posterior is tighter than the prior: a dense view shows tilt and height
    assert np.all(np.diag(fix.floor_covariance) < 0.1 * np.diag(prior[1]))


def test_a_pair_is_solved_on_the_carried_floor_and_leaves_it_as_it_was() -> None:
    cam = make_camera("equidistant", "upward")
    pose, tilt, dz = (2.0, 2.0, 0.2), (0.01, 0.012), 0.03
    P = GRID[[5, 6]]
    px = observe(cam, pose, P, tilt, dz)
    prior = ((tilt[0], tilt[1], dz), np.diag([1e-4, 1e-4, 1e-4]))
    fix = solve_pose(cam, px, P, initial=pose, config=TILT, floor_prior=prior)
    assert fix is not None and fix.floor is not None
    np.testing.assert_allclose([fix.x, fix.y, fix.theta], pose, atol=1e-6)  # on that floor
    np.testing.assert_array_equal(fix.floor, prior[0])
    assert fix.floor_covariance is None  # nothing learnt: the tracker carries the floor
    level = solve_pose(cam, px, P, initial=pose)  # the map's level floor: ~2.5 cm off
    assert level is not None and math.hypot(level.x - pose[0], level.y - pose[1]) > 0.02


def after_fix(floor: FloorPlane, fix, pose):
    """What the tracker does with a fix solved with the wide prior around `floor`."""
    carried = floor.prior(pose, CFG)
    if fix.floor_covariance is None:
        return floor, False
    e_f, P_f, _ = fused(carried, floor.widened(carried, CFG), fix.floor,
                        fix.floor_covariance, CFG.reset_chi2)  # fmt: skip
    return floor.updated((fix.x, fix.y, fix.theta), e_f, P_f), True


def test_the_carried_floor_learns_a_ramp_and_turns_its_tilt_with_the_heading() -> None:
    cam = make_camera("equidistant", "offset-tilted")
    h0, g = -0.03, np.array([0.035, 0.0])  # a 2 deg ramp rising along x
    rng = np.random.default_rng(4)
    floor, updates = FloorPlane.level(CFG), 0
    for k in range(15):  # drive along x at y = 2, one fix every 5 cm, 0.3 px noise
        pose = (1.6 + 0.05 * k, 2.0, 0.0)
        tilt, dz = on_plane(h0, g, pose[0], pose[1], pose[2])
        px = observe(cam, pose, GRID, tilt, dz) + rng.normal(0.0, 0.3, (len(GRID), 2))
        wide = floor.widened(floor.prior(pose, CFG), CFG)
        fix = solve_pose(cam, px, GRID, initial=pose, config=TILT,
                         pixel_sigma_px=0.3, floor_prior=wide)  # fmt: skip
        assert fix is not None and fix.floor is not None
        if fix.floor_covariance is None:  # the carried floor explains them: solved on it
            np.testing.assert_allclose(fix.floor, wide[0], atol=1e-12)
        floor, used = after_fix(floor, fix, pose)
        updates += used
    assert floor.at_xy is not None and 1 <= updates < 15
    np.testing.assert_allclose(floor.s[1:], g, atol=0.003)  # about 0.15 deg (of 2 deg)
    assert abs(floor.s[0] - (h0 + g @ floor.at_xy)) < 0.006  # of 5 cm
    # turned in place by 90 deg: the ramp now rises to the body's right (roll), not ahead
    (roll, pitch, dz), P = floor.prior((*floor.at_xy, math.pi / 2), CFG)
    assert abs(roll - math.atan(-g[0])) < 0.003 and abs(pitch) < 0.003
    # driven 1 m on, the height follows the plane, both returning towards the level floor,
    # and the uncertainty grew (eq. 3)
    (_, _, dz1), P1 = floor.prior((floor.at_xy[0] + 1.0, floor.at_xy[1], 0.0), CFG)
    a = math.exp(-1.0 / CFG.level_length_m)
    assert dz1 == pytest.approx(a * (dz + floor.s[1]), abs=1e-12)  # a (h + g . (p - p0))
    grown = floor.predicted(floor.at_xy[0] + 1.0, floor.at_xy[1], CFG).covariance
    assert np.all(np.diag(grown) > np.diag(floor.covariance))
    # the prior a fix gets is never tighter than the least sigmas (common errors)
    assert P[2, 2] >= CFG.min_sigma_m**2 and P1[0, 0] >= CFG.min_slope**2


def test_fusion_is_the_information_sum_and_a_disagreeing_floor_starts_anew() -> None:
    e0, Pc = np.array([0.01, -0.005, 0.02]), np.diag([1e-5, 4e-6, 1e-4])
    W = np.diag([4e-4, 4e-4, 2.5e-3])
    # a frame with information I on e (measurement z): its wide-prior posterior
    I, z = np.diag([1e5, 5e4, 1e4]), np.array([0.012, -0.004, 0.025])
    C_w = np.linalg.inv(np.linalg.inv(W) + I)
    e_w = C_w @ (np.linalg.inv(W) @ e0 + I @ z)
    e_f, P_f, reset = fused((tuple(e0), Pc), (tuple(e0), W), e_w, C_w, 11.34)
    P_exp = np.linalg.inv(np.linalg.inv(Pc) + I)
    assert not reset
    np.testing.assert_allclose(P_f, P_exp, rtol=1e-9)
    np.testing.assert_allclose(e_f, P_exp @ (np.linalg.inv(Pc) @ e0 + I @ z), atol=1e-12)
    # 3 deg off a floor known to 0.2 deg: a bump's flank, not the same floor
    z_bump = e0 + np.array([0.05, 0.0, 0.0])
    e_wb = C_w @ (np.linalg.inv(W) @ e0 + I @ z_bump)
    e_f, P_f, reset = fused((tuple(e0), Pc), (tuple(e0), W), e_wb, C_w, 11.34)
    assert reset and np.array_equal(e_f, e_wb) and np.array_equal(P_f, C_w)


def test_conditioning_the_pose_on_the_floor_is_exact_for_a_linear_model() -> None:
    # pose = p0 + J e + w: the joint covariance of a fit, then e fixed at e_f
    rng = np.random.default_rng(2)
    J, Ce, Cw = rng.normal(size=(3, 3)), np.diag([1e-4, 2e-4, 1e-3]), np.diag([1e-6] * 3)
    C_pp, C_pe = J @ Ce @ J.T + Cw, J @ Ce
    p0, e_w, e_f = np.array([1.0, 2.0, 0.3]), np.array([0.01, 0.0, 0.02]), np.zeros(3)
    pose_w = p0 + J @ e_w
    p, C = conditioned(tuple(pose_w), C_pp, C_pe, Ce, e_w, e_f)
    np.testing.assert_allclose(p, p0 + J @ e_f, atol=1e-12)
    np.testing.assert_allclose(C, Cw, atol=1e-12)


# -- the floor's significance against the calibration's error (`floor_change_chi2`) -----------
def undistorted(cam: CameraModel, px: np.ndarray, h: float = 0.5):
    """`solve_pose`'s normalised points m and A = d m / d pixel (forward differences)."""
    m = normalized_from_pixels(cam, px)
    step = np.array([[h, 0.0], [0.0, h]])
    mu, mv = normalized_from_pixels(cam, px + step[0]), normalized_from_pixels(cam, px + step[1])
    A = [((a[0] - b[0]) / h, (c[0] - b[0]) / h, (a[1] - b[1]) / h, (c[1] - b[1]) / h)
         for a, b, c in zip(mu, m, mv, strict=True)]  # fmt: skip
    return m.tolist(), A


@pytest.mark.parametrize("with_calibration", [True, False])
def test_the_floor_change_is_chi_square_with_the_calibrations_error_in_its_spread(
    with_calibration: bool,
) -> None:
    # A level floor at the prior's mean seen by a dense grid (49 landmarks) through a fisheye
    # whose calibration is off by a draw of its stated uncertainty, 0.3 px of white noise:
    # with the calibration's share in the floor's spread the statistic is chi-square with 3
    # dof (mean 3); with pixel noise alone it is several times that (the structured
    # residuals read as a floor).
    true = fisheye_camera()
    P = grid_positions(7, 7, 0.4)
    P[:, :2] += 1.0
    consider = CalibrationConsider.for_camera(true, focal_rel=0.002, principal_px=0.6,
                                              distortion_rel=0.05)  # fmt: skip
    pose = (2.2, 2.1, 0.7)
    px_true = observe(true, pose, P)
    level = FloorPlane.level(CFG)
    wide = level.widened(level.prior(pose, CFG), CFG)
    nonzero = np.flatnonzero(true.distortion != 0.0)
    rng = np.random.default_rng(7)
    stats = []
    for _ in range(100):
        dc = rng.normal(0.0, 1.0, len(consider.sigmas)) * consider.sigmas
        d = true.distortion.copy()
        d[nonzero] += dc[4:]
        cam = dataclasses.replace(true, fu=true.fu + dc[0], fv=true.fv + dc[1],
                                  cu=true.cu + dc[2], cv=true.cv + dc[3], distortion=d)  # fmt: skip
        px = px_true + rng.normal(0.0, 0.3, px_true.shape)
        m, A = undistorted(cam, px)
        z, P_xy = P[:, 2].tolist(), P[:, :2].tolist()
        fit = solve_tilted(m, A, z, P_xy, cam.T_body_camera, (*pose, 0.0, 0.0, 0.0),
                           0.3, None, 20, floor_prior=wide)  # fmt: skip
        assert fit is not None
        J = consider.scaled_jacobian(px) if with_calibration else np.zeros((len(P), 2, 1))
        chi2, _ = floor_change_chi2(m, A, z, P_xy, cam.T_body_camera, fit[0], fit[1],
                                    [0.3] * len(P), wide, J)  # fmt: skip
        stats.append(chi2)
    if with_calibration:
        assert 2.2 < np.mean(stats) < 3.9  # the mean of chi-square with 3 dof, +-2.5 its s.e.
        assert np.mean(np.array(stats) > 11.34) < 0.05  # its 99 % point
    else:
        assert np.mean(stats) > 10.0


def test_a_miscalibrated_dense_view_keeps_the_carried_floor_and_a_real_one_is_still_seen() -> None:
    # The realistic calibration error (focal 0.2 %, centre 0.6 px, distortion 5 %)
    # under a 40 cm grid with the wide radial-tangential lens: the pixel-noise test takes a
    # floor on level ground in some views; with the calibration in the test none, while a
    # floor 1 deg out of level and 3 cm high is still taken, within 0.2 deg and 2 cm.
    true = strong_radtan_camera()
    P = grid_positions(13, 11, 0.4)
    P[:, 2] += 0.03 * np.sin(np.arange(len(P)) * 1.7)
    level = FloorPlane.level(CFG)
    taken = {"noise only": 0, "with calibration": 0, "real floor": 0}
    for seed in range(10):
        rng = np.random.default_rng(seed)
        cam = miscalibrated(true, rng)
        noise = PixelNoiseModel(cam, PixelNoiseConfig(),
                                scale_px_per_m(cam.fu, 2.5 - cam.T_body_camera[2, 3]))  # fmt: skip
        pose = (2.4 + rng.uniform(-0.2, 0.2), 2.0 + rng.uniform(-0.2, 0.2), rng.uniform(-3, 3))
        wide = level.widened(level.prior(pose, CFG), CFG)
        for tilt, dz in (((0.0, 0.0), 0.0), ((0.0, 0.0175), 0.03)):
            T = T_world_body_from_pose(*pose)
            T[:3, :3] = rotation_world_body(pose[2], *tilt)
            T[2, 3] = dz
            px, valid = predict_pixels(true, T, P)
            inside = valid & np.all((px > 5) & (px < [635, 475]), axis=1)
            px = px[inside] + rng.normal(0.0, 0.1, (int(inside.sum()), 2))
            sig = [noise.sigma_px(u, v) for u, v in px]
            for key, cj in (("noise only", None), ("with calibration", noise.calibration_jacobian)):
                if dz and key == "noise only":
                    continue
                fix = solve_pose(cam, px, P[inside], initial=pose, config=TILT,
                                 pixel_sigma_px=sig, floor_prior=wide,
                                 calibration_jacobian=cj)  # fmt: skip
                assert fix is not None and fix.floor is not None
                if fix.floor_covariance is None:
                    continue
                if not dz:
                    taken[key] += 1
                    continue
                taken["real floor"] += 1
                np.testing.assert_allclose(fix.floor[:2], tilt, atol=math.radians(0.2))
                assert abs(fix.floor[2] - dz) < 0.02  # the focal length's error reads as height
    assert taken["noise only"] >= 3
    assert taken["with calibration"] == 0
    assert taken["real floor"] == 10


def test_the_fused_floor_holds_the_calibrations_error_as_eq_6_has_it() -> None:
    # eq. (6) is the derivative of the fusion (4) in the calibration's error: perturb the
    # carried floor by K_c dc and the fix's by E_w dc, and the fused floor moves by K_f dc
    rng = np.random.default_rng(3)
    pose = (1.0, 2.0, 0.8)
    carried = FloorPlane.level(CFG).prior(pose, CFG)
    wide = FloorPlane.level(CFG).widened(carried, CFG)
    C_w = np.diag([0.004, 0.005, 0.02]) ** 2
    e_w = np.array([0.006, -0.004, 0.01])
    K_c, E_w = rng.normal(0.0, 1e-3, (3, 5)), rng.normal(0.0, 1e-3, (3, 5))
    e_f, P_f, reset = fused(carried, wide, e_w, C_w, CFG.reset_chi2)
    assert not reset
    K_f = fused_sensitivity(carried, wide, C_w, P_f, K_c, E_w, reset)
    assert K_f is not None
    dc = rng.normal(0.0, 1.0, 5)
    moved = ((carried[0] + K_c @ dc), carried[1])
    e_moved, _, _ = fused(moved, (moved[0], wide[1]), e_w + E_w @ dc, C_w, CFG.reset_chi2)
    np.testing.assert_allclose(e_moved - e_f, K_f @ dc, rtol=1e-9, atol=1e-12)
    # a reset takes the fix's; the carried floor's frame is the fix's B K, round trip
    assert fused_sensitivity(carried, wide, C_w, P_f, K_c, E_w, True) is E_w
    floor = FloorPlane.level(CFG).updated(pose, e_f, P_f, K_f)
    at = floor.sensitivity_at(pose, CFG)
    assert at is not None
    np.testing.assert_allclose(at, K_f, atol=1e-15)
    # driven 1.5 m on: K decays with the state toward the level floor, a F K (eq. 3)
    ahead = floor.predicted(pose[0] + 1.5, pose[1], CFG)
    assert ahead.sensitivity is not None and floor.sensitivity is not None
    F = np.array([[1.0, 1.5, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    np.testing.assert_allclose(ahead.sensitivity, math.exp(-0.5) * F @ floor.sensitivity)


def test_the_fixs_floor_sensitivity_is_the_derivative_of_its_floor_in_the_calibration() -> None:
    # E of `floor_change_chi2` (the fix's `floor_sensitivity`) against finite differences:
    # hand the fit a calibration moved by a tenth of a standard deviation of each parameter
    # in turn, and the prior's floor by as much of its own sensitivity K0; the fit's floor
    # moves by E times that (a 40 cm grid, the wide radial-tangential lens, 1 deg of floor).
    true = strong_radtan_camera()
    P = grid_positions(13, 11, 0.4)
    noise = PixelNoiseModel(true, PixelNoiseConfig(),
                            scale_px_per_m(true.fu, 2.5 - true.T_body_camera[2, 3]))  # fmt: skip
    pose = (2.4, 2.0, 0.3)
    T = T_world_body_from_pose(*pose)
    T[:3, :3] = rotation_world_body(pose[2], 0.0, 0.0175)
    px, valid = predict_pixels(true, T, P)
    inside = valid & np.all((px > 5) & (px < [635, 475]), axis=1)
    px, P = px[inside], P[inside]
    sig = [noise.sigma_px(u, v) for u, v in px]
    level = FloorPlane.level(CFG)
    wide = level.widened(level.prior(pose, CFG), CFG)
    sigmas = noise.consider.sigmas
    K0 = np.random.default_rng(0).normal(0.0, 0.002, (3, len(sigmas)))

    def floor_of(cam: CameraModel, prior_mean: np.ndarray):
        fix = solve_pose(cam, px, P, initial=pose, config=ALWAYS_TILT, pixel_sigma_px=sig,
                         floor_prior=(tuple(prior_mean), wide[1]),
                         calibration_jacobian=noise.calibration_jacobian,
                         floor_sensitivity=K0)  # fmt: skip
        assert fix is not None and fix.floor is not None
        return fix

    base = floor_of(true, np.array(wide[0]))
    assert base.floor_sensitivity is not None
    nonzero = np.flatnonzero(true.distortion != 0.0)
    h = 0.1
    columns = []
    for j, sj in enumerate(sigmas):
        if j < 4:
            name = ("fu", "fv", "cu", "cv")[j]
            cam = dataclasses.replace(true, **{name: getattr(true, name) + h * sj})
        else:
            d = true.distortion.copy()
            d[nonzero[j - 4]] += h * sj
            cam = dataclasses.replace(true, distortion=d)
        columns.append((floor_of(cam, np.array(wide[0]) + h * K0[:, j]).floor - base.floor) / h)
    np.testing.assert_allclose(np.array(columns).T, base.floor_sensitivity, rtol=0.05, atol=1e-4)
