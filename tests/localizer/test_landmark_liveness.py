"""What tracking learnt of each landmark (lit, dark, unknown) and what its absence weighs
against a pose hypothesis (`localizer/landmark_liveness.py`)."""

from __future__ import annotations

import math

import numpy as np

from localizer.camera import T_body_camera_upward, predict_pixels
from localizer.config import FusionConfig, LocalizerConfig
from localizer.events import OdometryMeasured, PoseEstimate, SpotsObserved
from localizer.geometry import T_world_body_from_pose
from localizer.landmark_liveness import LandmarkLiveness
from localizer.landmark_map import LandmarkMap
from localizer.localizer import Localizer
from localizer.relocalization import RelocalizationConfig
from localizer.robot import RobotGeometry
from tests.localizer.cases import fisheye_camera, grid_positions

CFG = RelocalizationConfig()
CAM = fisheye_camera(T_body_camera_upward(height=0.3))


def test_nothing_known_weighs_the_pessimistic_prior() -> None:
    w = LandmarkLiveness(5, CFG).miss_log_lr()
    # dark or hidden 1 in 5, else missed 1 in 50: -ln(0.2 + 0.8 * 0.02)
    np.testing.assert_allclose(w, -math.log(0.216), rtol=1e-12)
    assert CFG.miss_log_lr == w[0]


def test_a_landmark_seen_lit_weighs_more_and_one_never_seen_in_view_nothing() -> None:
    lv = LandmarkLiveness(4, CFG)
    # 10 frames: rows 0 and 1 in view and detected, row 2 in view and never detected,
    # row 3 never in view
    for _ in range(10):
        lv.observe(np.array([0, 1, 2]), np.array([0, 1]))
    assert lv.in_view == 20 and lv.missed == 0
    m = (0 + 0.02 * 50) / (20 + 50)  # the miss rate, its prior weighing 50 landmark-frames
    assert math.isclose(lv.miss_rate(), m)
    w = lv.miss_log_lr()
    lit = -math.log(0.01 + 0.99 * m)
    dark = 0.2 / (0.2 + 0.8 * m**10)  # Bayes: never detected on 10 frames
    np.testing.assert_allclose(w[:2], lit)
    np.testing.assert_allclose(w[2], -math.log(dark + (1 - dark) * m))
    assert w[2] < 1e-9 * w[0]  # known dark: its absence is no evidence for anyone
    np.testing.assert_allclose(w[3], -math.log(0.2 + 0.8 * m))


def test_a_first_detection_turns_the_frames_it_was_unseen_into_misses() -> None:
    lv = LandmarkLiveness(2, CFG)
    for _ in range(3):
        lv.observe(np.array([0, 1]), np.array([0]))
    lv.observe(np.array([0, 1]), np.array([0, 1]))  # row 1 was lit, missed three times
    assert lv.unseen.tolist() == [0, 0] and lv.lit.tolist() == [True, True]
    assert (lv.in_view, lv.missed) == (3 + 3 + 2, 3)
    assert math.isclose(lv.miss_rate(), (3 + 1.0) / (8 + 50))


def test_only_landmarks_well_in_view_of_the_fused_pose_are_counted() -> None:
    P = grid_positions(8, 8, 0.4)
    pose = (1.4, 1.4, 0.3)
    px, ok = predict_pixels(CAM, T_world_body_from_pose(*pose), P)
    r = np.hypot(px[:, 0] - CAM.cu, px[:, 1] - CAM.cv)
    rows = np.nonzero(ok)[0]
    near = rows[r[rows] < 150.0]  # the spots detected: within 150 px of the centre
    lv = LandmarkLiveness(len(P), CFG)
    lv.observe_frame(CAM, pose, P, rows, near[:-1], px[near[:-1]])
    r_seen = float(np.max(r[near[:-1]]))
    inner = rows[r[rows] <= r_seen - CFG.miss_margin_px]
    # counted: those well inside the radius the detections reach; of them, all but one lit
    assert set(np.nonzero(lv.lit)[0]) == set(near[:-1].tolist())
    assert set(np.nonzero(lv.unseen)[0]) == set(inner.tolist()) - set(near[:-1].tolist())
    assert lv.in_view == len(set(inner.tolist()) & set(near[:-1].tolist()))


def test_the_localizer_learns_while_tracking_which_landmarks_are_lit_and_which_dead() -> None:
    # a 6 x 6 grid 40 cm apart; the landmark at (1.2, 1.2) is mapped but its LED is dead;
    # the robot, told where it starts, drives 1 m along y = 1.0 at 0.5 m/s (15 Hz camera)
    P = grid_positions(6, 6, 0.4)
    dead = int(np.argmin(np.hypot(P[:, 0] - 1.2, P[:, 1] - 1.2)))
    lit = np.ones(len(P), dtype=bool)
    lit[dead] = False
    fusion = FusionConfig(initial_sigma_m=0.02, initial_sigma_rad=0.02)
    loc = Localizer(CAM, LandmarkMap(np.arange(1, len(P) + 1), P),
                    RobotGeometry(wheel_base=0.36, max_speed=1.0),
                    LocalizerConfig(fusion=fusion))  # fmt: skip
    loc.set_initial_pose(0.5, 1.0, 0.0, 0)
    rng = np.random.default_rng(1)
    for k in range(1, 31):
        t_ns = k * 66_666_667
        loc.handle(OdometryMeasured(t_ns, 0.5, 0.5))
        pose = (0.5 + 0.5 * t_ns * 1e-9, 1.0, 0.0)
        near = lit & (np.hypot(P[:, 0] - pose[0], P[:, 1] - pose[1]) <= 1.0)
        px, ok = predict_pixels(CAM, T_world_body_from_pose(*pose), P[near])
        px = px[ok] + rng.normal(0.0, 0.3, (int(ok.sum()), 2))
        est = loc.handle(SpotsObserved(t_ns, px, np.ones(len(px)), np.full(len(px), 9.0)))[0]
        assert isinstance(est, PoseEstimate) and est.mode == "landmark"
    lv = loc.liveness
    w = lv.miss_log_lr()
    assert not lv.lit[dead] and lv.unseen[dead] >= 5  # in view on every observed frame
    assert w[dead] < 1e-6  # known dark: its absence is evidence for no one
    assert np.count_nonzero(lv.lit) >= 12 and lv.missed == 0
    np.testing.assert_allclose(w[lv.lit], -math.log(0.01 + 0.99 * lv.miss_rate()))
    assert np.all(w[lv.lit] > 4.0)
