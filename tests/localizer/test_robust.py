"""Issue 12's robustness pieces, each on its own: the robust loss, the pixel-noise model and
its adaptation, the rotation-following second hypothesis of a tracking step, and the
hypothesis scoring of re-localization without LEDs."""

from __future__ import annotations

import math

import numpy as np
import pytest

from localizer.camera import T_body_camera_upward, predict_pixels
from localizer.config import LocalizerConfig
from localizer.events import FrameObserved
from localizer.geometry import T_world_body_from_pose
from localizer.landmark_map import LandmarkMap
from localizer.landmark_tracker import LandmarkTracker
from localizer.noise_model import PixelNoiseConfig, PixelNoiseModel, calibration_sigma_table
from localizer.pose import solve_pose
from localizer.pose_config import PoseSolveConfig
from localizer.pose_filter import PoseFilter
from localizer.pose_planar import cauchy_weight, huber_weight
from localizer.relocalization import RelocalizationConfig, relocalize
from localizer.robot import RobotGeometry
from sim.render import render_frame
from tests.localizer.cases import (
    fisheye_camera,
    grid_positions,
    irregular_positions,
    strong_radtan_camera,
)

CAM = strong_radtan_camera()
RING = np.array([[1.0 + 0.6 * math.cos(a), 1.0 + 0.6 * math.sin(a), 2.5]
                 for a in np.linspace(0, 2 * math.pi, 8, endpoint=False)])  # fmt: skip


def test_robust_weights() -> None:
    assert huber_weight(1.5, 2.0) == 1.0 and huber_weight(8.0, 2.0) == 0.25
    assert cauchy_weight(0.0, 2.0) == 1.0 and cauchy_weight(2.0, 2.0) == 0.5


@pytest.mark.parametrize("loss", ["huber", "cauchy"])
def test_one_bad_spot_pulls_a_robust_fix_far_less_than_least_squares(loss: str) -> None:
    pose = (1.02, 0.97, 0.3)
    px, ok = predict_pixels(CAM, T_world_body_from_pose(*pose), RING)
    assert ok.all()
    bad = px.copy()
    bad[3] += (15.0, -10.0)  # a glint taken for landmark 3
    plain = solve_pose(CAM, bad, RING, pixel_sigma_px=0.5)
    robust = solve_pose(
        CAM, bad, RING, pixel_sigma_px=0.5, config=PoseSolveConfig(loss=loss, loss_scale=2.0)
    )
    assert plain is not None and robust is not None
    err = lambda f: math.hypot(f.x - pose[0], f.y - pose[1])  # noqa: E731
    assert err(plain) > 4e-3  # least squares spreads the bad spot over the pose
    assert err(robust) < 0.25 * err(plain)
    # and the bad landmark stands out in the residuals
    assert int(np.argmax(robust.residuals_px)) == 3 and robust.residuals_px[3] > 10.0
    assert max(np.delete(robust.residuals_px, 3)) < 1.5


def test_pixel_sigma_grows_with_radius_and_calibration_uncertainty() -> None:
    cfg = PixelNoiseConfig()
    _, sig = calibration_sigma_table(CAM, cfg)
    assert sig[0] == pytest.approx(cfg.principal_px, abs=0.05)  # the centre: only the centre
    assert np.all(np.diff(sig) >= -1e-6) and sig[-1] > 4.0  # k1 -0.28 +-5 %: px at the edge
    exact = calibration_sigma_table(CAM, PixelNoiseConfig(focal_rel=0, principal_px=0,
                                                          distortion_rel=0))[1]  # fmt: skip
    np.testing.assert_allclose(exact, 0.0, atol=1e-9)
    fish = calibration_sigma_table(fisheye_camera(), cfg)[1]
    assert fish[-1] < sig[-1]  # a mild fisheye's coefficients are small


def test_noise_factor_follows_the_residuals_within_its_bounds() -> None:
    model = PixelNoiseModel(CAM, PixelNoiseConfig(adapt_gain=0.1), scale_px_per_m=136.0)
    centre = model.sigma_px(CAM.cu, CAM.cv)
    # chi-square is over the model's current sigmas (the factor included)
    for _ in range(200):  # residuals four times the prior's
        model.observe(16.0 * (2 * 10 - 3) / model.factor**2, 10)
    assert model.factor == pytest.approx(3.0)  # the upper bound (a prior, not a free fit)
    assert model.sigma_px(CAM.cu, CAM.cv) == pytest.approx(3.0 * centre)
    for _ in range(300):  # residuals as the prior says bring it back to 1
        model.observe(1.0 * (2 * 10 - 3) / model.factor**2, 10)
    assert model.factor == pytest.approx(1.0, abs=0.02)
    model.observe(1e9, 2)  # too few landmarks (a pair: 1 dof): ignored
    assert model.factor == pytest.approx(1.0, abs=0.02)


def test_a_turn_started_after_the_last_odometry_sample_is_followed() -> None:
    # 40 cm grid under a fisheye: driving, and since the last sample (16 ms ago) the robot
    # turns at 3 rad/s: spots at the image edge moved ~15 px, a quarter of the spacing.
    cam = fisheye_camera(T_body_camera_upward(height=0.3))
    grid = grid_positions(12, 8, 0.4, 2.5)
    lmap = LandmarkMap(np.arange(1, len(grid) + 1), grid)
    robot = RobotGeometry(0.36, 1.5)
    truth = (2.0, 1.4, 3.0 * 0.016)
    img = render_frame(cam, T_world_body_from_pose(*truth), grid, np.ones(len(grid)),
                       rng=np.random.default_rng(0))  # fmt: skip
    tracker = LandmarkTracker(cam, robot, LocalizerConfig(), lmap)
    confident = np.diag([0.002**2, 0.002**2, 0.0005**2])
    args = dict(dt_frame_s=1 / 30, fresh_odometry=True, candidates=None)
    filt = PoseFilter(2.0, 1.4, 0.0, confident, wheel_base=0.36)
    first = tracker.step(filt, FrameObserved(0, img), **args)  # type: ignore[arg-type]
    assert first.used == ()  # (without the second hypothesis: the fix disagrees)
    filt = PoseFilter(2.0, 1.4, 0.0, confident, wheel_base=0.36)
    res = tracker.step(filt, FrameObserved(0, img), since_sample_s=0.016, **args)  # type: ignore[arg-type]
    assert len(res.used) > 40
    assert (
        abs(filt.pose[2] - truth[2]) < 0.002
        and math.hypot(filt.pose[0] - 2.0, filt.pose[1] - 1.4) < 0.003
    )


def test_a_wheel_slipping_since_the_last_fix_is_followed() -> None:
    # 2 m/s over a wet patch: since the last fix (one 12 Hz frame, 17 cm of travel) the
    # odometry turned 1.4 deg the robot did not; a fresh sample, so no speed-change term
    cam = fisheye_camera(T_body_camera_upward(height=0.3))
    grid = grid_positions(12, 8, 0.4, 2.5)
    lmap = LandmarkMap(np.arange(1, len(grid) + 1), grid)
    truth = (2.0, 1.4, 0.0)
    img = render_frame(cam, T_world_body_from_pose(*truth), grid, np.ones(len(grid)),
                       rng=np.random.default_rng(0))  # fmt: skip
    tracker = LandmarkTracker(cam, RobotGeometry(0.36, 2.0), LocalizerConfig(), lmap)
    confident = np.diag([0.002**2, 0.002**2, 0.0005**2])
    args = dict(dt_frame_s=1 / 12, fresh_odometry=True, candidates=None, since_sample_s=0.0)
    slipped = (2.0, 1.4, -math.radians(1.4))
    filt = PoseFilter(*slipped, confident, wheel_base=0.36)
    assert tracker.step(filt, FrameObserved(0, img), **args).used == ()  # type: ignore[arg-type]
    filt = PoseFilter(*slipped, confident, wheel_base=0.36)
    res = tracker.step(filt, FrameObserved(0, img), travel_since_fix_m=0.167, **args)  # type: ignore[arg-type]
    assert len(res.used) > 40
    assert abs(filt.pose[2] - truth[2]) < 0.002
    assert math.hypot(filt.pose[0] - truth[0], filt.pose[1] - truth[1]) < 0.003


def _spots(cam, positions, pose):
    px, ok = predict_pixels(cam, T_world_body_from_pose(*pose), positions)
    return px[ok] + np.random.default_rng(1).normal(0, 0.3, (int(ok.sum()), 2))


def test_relocalization_on_a_regular_grid_uses_the_prior_or_says_nothing() -> None:
    cam = fisheye_camera(T_body_camera_upward(height=0.3))
    grid = grid_positions(30, 30, 0.4, 2.5)  # a large grid: its edge is out of view
    truth = (6.0, 6.0, 0.2)
    spots = _spots(cam, grid, truth)
    cfg = RelocalizationConfig()
    good = relocalize(cam, grid, spots, (6.05, 5.97, 0.22), np.diag([0.05**2] * 2 + [0.05**2]), cfg)
    assert good.accepted and good.pose is not None
    assert math.hypot(good.pose[0] - 6.0, good.pose[1] - 6.0) < 0.01
    assert len(good.pairs) > 40
    # A prior wider than the spacing: the shifted hypotheses explain the spots as well.
    wide = relocalize(cam, grid, spots, (6.1, 5.9, 0.2), np.diag([0.5**2, 0.5**2, 0.3**2]), cfg)
    assert not wide.accepted and wide.second > wide.score - cfg.margin


def test_relocalization_of_a_kidnapped_robot_on_an_irregular_ceiling() -> None:
    cam = fisheye_camera(T_body_camera_upward(height=0.3))
    ceiling = irregular_positions(np.random.default_rng(7), 0, (6.0, 4.0), spacing=0.5)
    truth = (3.4, 2.1, 2.2)
    spots = _spots(cam, ceiling, truth)
    # the prior: where it was before it was carried off, any heading
    found = relocalize(cam, ceiling, spots, (2.3, 1.6, 0.5), np.diag([1.0, 1.0, math.pi**2]),
                       RelocalizationConfig())  # fmt: skip
    assert found.accepted and found.pose is not None
    assert math.hypot(found.pose[0] - truth[0], found.pose[1] - truth[1]) < 0.03
    assert abs(found.pose[2] - truth[2]) < 0.02
    assert found.score - found.second >= RelocalizationConfig().margin


def test_odometry_noise_grows_when_fixes_keep_surprising_the_filter() -> None:
    from localizer.pose import PoseFix

    filt = PoseFilter(0.0, 0.0, 0.0, np.diag([1e-4, 1e-4, 1e-4]), wheel_base=0.36)
    rng = np.random.default_rng(0)
    R = np.diag([1e-6, 1e-6, 1e-6])
    for _ in range(600):  # the robot drifts 5 mm per frame sideways, which odometry misses
        filt.predict(0.3, 0.3, 1 / 30)
        x, y, th = filt.pose
        fix = PoseFix(x + rng.normal(0, 0.005), y + rng.normal(0, 0.005), th, R)
        filt.update_fix(fix)
    assert filt.noise_scale > 2.0  # NIS / 3 >> 1: the odometry is noisier than configured
    assert filt.noise_scale <= filt.config.noise_scale_bounds[1]
    calm = PoseFilter(0.0, 0.0, 0.0, np.diag([1e-4] * 3), wheel_base=0.36)
    for _ in range(300):
        calm.predict(0.3, 0.3, 1 / 30)
        calm.update_fix(PoseFix(*calm.pose, R))
    assert calm.noise_scale == pytest.approx(calm.config.noise_scale_bounds[0])


def test_an_edge_spot_paired_with_a_landmark_outside_the_image_is_flagged() -> None:
    cam = fisheye_camera(T_body_camera_upward(height=0.3))
    grid = grid_positions(12, 8, 0.4, 2.5)
    lmap = LandmarkMap(np.arange(1, len(grid) + 1), grid)
    tracker = LandmarkTracker(cam, RobotGeometry(0.36, 1.5), LocalizerConfig(), lmap)
    pose = (2.0, 1.4, 0.0)
    px, ok = predict_pixels(cam, T_world_body_from_pose(*pose), grid)
    inside = [int(i) for i in np.nonzero(ok)[0]]
    outside = next(int(i) for i in np.nonzero(~ok)[0])  # a landmark out of view
    border = [3.0, cam.cv]  # a spot 3 px from the left edge
    rows = [inside[0], inside[1], outside]
    spots = [px[inside[0]].tolist(), px[inside[1]].tolist(), border]
    assert tracker._off_image(rows[:2], spots[:2], pose) == set()
    assert tracker._off_image(rows, spots, pose) == {2}
    # a landmark in view but far from the border spot it was paired with
    assert tracker._off_image([inside[0], inside[1]], [spots[0], border], pose) == {1}
