"""Recovery from `lost` without LEDs: hypotheses scored by every spot and by the landmarks a
hypothesis predicts where no spot is, carried by the odometry, and accepted only when
unambiguous (`localizer/hypothesis_scoring.py`, `localizer/relocalization.py`,
`localizer/hypothesis_set.py`)."""

from __future__ import annotations

import math

import numpy as np

from localizer.camera import T_body_camera_upward, predict_pixels
from localizer.config import FusionConfig, LocalizerConfig
from localizer.events import OdometryMeasured, PoseEstimate, SpotsObserved
from localizer.geometry import T_world_body_from_pose, wrap_angle
from localizer.hypothesis_scoring import frame_log_lr, frame_view
from localizer.hypothesis_set import HypothesisSet, compose_odometry
from localizer.landmark_liveness import LandmarkLiveness
from localizer.landmark_map import LandmarkMap
from localizer.localizer import Localizer
from localizer.relocalization import RelocalizationConfig
from localizer.robot import RobotGeometry
from tests.localizer.cases import fisheye_camera, grid_positions

CAM = fisheye_camera(T_body_camera_upward(height=0.3))
CFG = RelocalizationConfig()
SEEN_M = 1.0  # spots farther than this (horizontally) fade below the threshold


def _spots(positions, pose, rng=None, seen_m=SEEN_M):
    """The landmarks' pixels from a pose, those within `seen_m` of it (a fading view)."""
    near = np.hypot(positions[:, 0] - pose[0], positions[:, 1] - pose[1]) <= seen_m
    px, ok = predict_pixels(CAM, T_world_body_from_pose(*pose), positions[near])
    px = px[ok]
    return px if rng is None else px + rng.normal(0.0, 0.3, px.shape)


def _hall(gap: bool):
    """16 x 10 landmarks 40 cm apart (a 6.0 x 3.6 m hall); with `gap`, the nine under a
    skylight (columns 12-14, rows 6-8, centre (5.2, 2.8)) are missing: the grid is no
    longer symmetric. (Each landmark missing in view counts once against a hypothesis, 1.5:
    a gap of four would be too little evidence for the margin of 9 on its own.)"""
    P = grid_positions(16, 10, 0.4)
    if gap:
        c, r = np.round(P[:, 0] / 0.4), np.round(P[:, 1] / 0.4)
        P = P[~(np.isin(c, (12, 13, 14)) & np.isin(r, (6, 7, 8)))]
    return P


def test_odometry_moves_each_hypothesis_in_its_own_frame() -> None:
    hyps = np.array([[1.0, 2.0, math.pi / 2], [0.0, 0.0, 0.0]])
    # 1 m forward and a 0.5 rad turn, in an odometry frame turned by 90 deg
    moved = compose_odometry(hyps, (5.0, 5.0, math.pi / 2), (5.0, 6.0, math.pi / 2 + 0.5))
    np.testing.assert_allclose(moved, [[1.0, 3.0, math.pi / 2 + 0.5], [1.0, 0.0, 0.5]],
                               atol=1e-12)  # fmt: skip
    back = compose_odometry(moved, (5.0, 6.0, math.pi / 2 + 0.5), (5.0, 5.0, math.pi / 2))
    np.testing.assert_allclose(back, hyps, atol=1e-12)


def test_every_spot_counts_for_a_hypothesis_and_every_missing_landmark_against() -> None:
    # 6 x 3 landmarks, the robot near the left edge: all 18 in view.
    P = grid_positions(6, 3, 0.4)
    truth = (0.4, 0.4, 0.3)
    view = frame_view(CAM, P, _spots(P, truth, seen_m=10.0), CFG)
    assert view is not None and len(view.pixels) == 18
    hyps = np.array([truth, (0.8, 0.4, 0.3), (0.0, 0.4, 0.3)])
    _, score, inliers, done = frame_log_lr(CAM, view, hyps, CFG)
    assert np.all(done)
    # the truth: 18 inliers. One spacing to the right: the right column's 3 spots match
    # nothing, and the left column is predicted where the image shows none (3 misses).
    # One spacing to the left: 3 spots match nothing; the right column it predicts lies
    # farther out than any spot is seen, so it is not held against it.
    np.testing.assert_array_equal(inliers, [18, 15, 15])
    lr_in, lr_miss = CFG.inlier_log_lr, CFG.miss_log_lr
    np.testing.assert_allclose(score, [18 * lr_in, 15 * lr_in - 3 * lr_miss, 15 * lr_in])


def _drive(hs, P, start, heading, speed, seconds, prior, rng):
    """Drive straight from `start`; odometry exact but in its own frame. Returns
    [(t_s, true pose, outcome)] per frame (10 Hz)."""
    out = []
    odo_offset = np.array([2.0, -1.0, 0.7])
    for k in range(int(seconds * 10) + 1):
        t = k / 10
        pose = (start[0] + speed * t * math.cos(heading),
                start[1] + speed * t * math.sin(heading), heading)  # fmt: skip
        co, so = math.cos(odo_offset[2]), math.sin(odo_offset[2])
        odo = (odo_offset[0] + co * pose[0] - so * pose[1],
               odo_offset[1] + so * pose[0] + co * pose[1],
               float(wrap_angle(pose[2] + odo_offset[2])))  # fmt: skip
        r = hs.update(int(t * 1e9), odo, CAM, P, _spots(P, pose, rng), *prior)
        out.append((t, pose, r))
    return out


PRIOR = ((3.0, 1.8, 0.0), np.diag([2.5**2, 2.5**2, math.pi**2]))  # anywhere in the hall
START = (2.6, 1.8)  # mid-hall: nothing but the regular grid in view


def test_a_symmetric_grid_stays_ambiguous_however_far_it_drives() -> None:
    hs = HypothesisSet(CFG)
    run = _drive(hs, _hall(gap=False), START, 0.3, 0.6, 4.0, PRIOR, np.random.default_rng(2))
    assert not any(r.accepted for _, _, r in run)
    # the truth and its twin turned by half a turn about the hall's centre (3.0, 1.8)
    # explain every view of the drive alike: both are among the best, within the margin
    pose = run[-1][1]
    last = [r for _, _, r in run if r.pose is not None][-1]  # the last frame scored
    twin = (6.0 - pose[0], 3.6 - pose[1])
    top = hs.poses[hs.log_lr >= np.max(hs.log_lr) - CFG.margin]
    for p in (pose, twin):
        assert np.min(np.hypot(top[:, 0] - p[0], top[:, 1] - p[1])) < 0.03
    assert last.score - last.second < CFG.margin


def test_driving_on_until_the_gap_comes_into_view_resolves_it() -> None:
    P = _hall(gap=True)
    hs = HypothesisSet(CFG)
    run = _drive(hs, P, START, 0.3, 0.6, 5.5, PRIOR, np.random.default_rng(3))
    accepted = [(t, pose, r) for t, pose, r in run if r.accepted]
    assert accepted, "never accepted"
    for _, pose, r in accepted:  # never a wrong fix
        assert r.pose is not None
        assert math.hypot(r.pose[0] - pose[0], r.pose[1] - pose[1]) < 0.02
        assert abs(wrap_angle(r.pose[2] - pose[2])) < 0.01
    # not before the skylight (5.2, 2.8) is in view (the hall's edges never are)
    t_first, pose, r = accepted[0]
    assert math.hypot(5.2 - pose[0], 2.8 - pose[1]) < SEEN_M + 0.8 and t_first > 1.0
    assert len(r.pairs) >= CFG.min_inlier_fraction * len(_spots(P, pose))


def _drive_accepts(P, miss_weights, seed):
    """`_drive` from mid-hall towards a gap at (5.0, 2.6) for 3 s, each landmark's absence
    weighing `miss_weights`; returns the (t, true pose, outcome) of the accepted frames."""
    hs = HypothesisSet(CFG)
    out = []
    odo_offset = np.array([2.0, -1.0, 0.7])
    rng = np.random.default_rng(seed)
    heading, speed, start = 0.3, 0.6, (3.4, 2.0)  # the gap 1.7 m ahead, out of view
    for k in range(31):
        t = k / 10
        pose = (start[0] + speed * t * math.cos(heading),
                start[1] + speed * t * math.sin(heading), heading)  # fmt: skip
        co, so = math.cos(odo_offset[2]), math.sin(odo_offset[2])
        odo = (odo_offset[0] + co * pose[0] - so * pose[1],
               odo_offset[1] + so * pose[0] + co * pose[1], pose[2] + odo_offset[2])  # fmt: skip
        r = hs.update(int(t * 1e9), odo, CAM, P, _spots(P, pose, rng), *PRIOR, miss_weights)
        if r.accepted:
            out.append((t, pose, r))
    return out


def test_a_gap_of_four_resolves_only_when_the_landmarks_are_known_lit() -> None:
    # four landmarks missing (columns 12-13, rows 6-7): the truth's twins (half a turn about
    # the centre, grid copies) predict four landmarks there; nothing known of them, that is
    # 4 x 1.53 = 6.1 of evidence, under the margin of 9: no acceptance
    P = grid_positions(16, 10, 0.4)
    c, r = np.round(P[:, 0] / 0.4), np.round(P[:, 1] / 0.4)
    P = P[~(np.isin(c, (12, 13)) & np.isin(r, (6, 7)))]
    assert not _drive_accepts(P, None, 6)
    # every landmark seen lit while tracking (1 in 100 dark since; detections missed 1 in
    # 1000): each absence weighs 4.5, the four 18; the truth is taken, and only it
    seen = LandmarkLiveness(len(P), CFG)
    seen.observe(np.arange(len(P)), np.arange(len(P)))
    seen.in_view, seen.missed = 1000, 0
    w = seen.miss_log_lr()
    np.testing.assert_allclose(w, -math.log(0.01 + 0.99 * 1.0 / 1050), rtol=1e-9)
    accepted = _drive_accepts(P, w, 6)
    assert accepted, "never accepted"
    for _, pose, r in accepted:
        assert r.pose is not None
        assert math.hypot(r.pose[0] - pose[0], r.pose[1] - pose[1]) < 0.02
        assert abs(wrap_angle(r.pose[2] - pose[2])) < 0.01


def test_a_late_comer_as_good_as_the_best_blocks_the_acceptance() -> None:
    P = _hall(gap=False)
    truth = (2.6, 1.8, 0.3)
    wrong = (3.0, 1.8, 0.3)  # one spacing off: mid-hall it explains every spot as well
    tight = ((wrong[0], wrong[1], wrong[2]), np.diag([0.05**2, 0.05**2, 0.05**2]))
    rng = np.random.default_rng(4)

    def frames(hs, prior, k0, n):
        return [hs.update(int(k * 0.2e9), (0.0, 0.0, 0.0), CAM, P, _spots(P, truth, rng), *prior)
                for k in range(k0, k0 + n)]  # fmt: skip

    # A prior that only allows the wrong pose: it is taken (the prior is the evidence).
    hs = HypothesisSet(CFG)
    assert frames(hs, tight, 0, 4)[-1].accepted
    # Seeded under that prior, then the prior widens (driven far since): the truth and the
    # other copies join the set as good as the best, and nothing is accepted.
    hs = HypothesisSet(CFG)
    frames(hs, tight, 0, 1)
    outcomes = frames(hs, PRIOR, 1, 10)
    assert not any(r.accepted for r in outcomes)
    assert np.min(np.hypot(hs.poses[:, 0] - truth[0], hs.poses[:, 1] - truth[1])) < 0.03


Run = list[tuple[float, str, float]]


def _kidnap(
    P: np.ndarray, A: tuple[float, float, float], B: tuple[float, float, float], seconds: float
) -> Run:
    """The Localizer end to end (no LED control, a 15 Hz camera): parked at A and tracking,
    lifted at 1 s and carried to B and turned (odometry still, 1 s), put down, driving on
    from 2.3 s at 0.6 m/s. Returns (t s, mode, position error m) per frame."""
    # told where it starts; lost after 1 s of frames no fix explains
    start = FusionConfig(
        initial_sigma_m=0.05, initial_sigma_rad=0.05, lost_after_rejections=15, carry_speed_m_s=1.0
    )
    robot = RobotGeometry(wheel_base=0.36, max_speed=1.0)
    lm = LandmarkMap(np.arange(1, len(P) + 1), P)
    loc = Localizer(CAM, lm, robot, LocalizerConfig(fusion=start))
    v = 0.6

    def truth(t: float) -> tuple[tuple[float, float, float], float, float]:
        """(pose, lift m, wheel speed m/s) at t."""
        if t < 1.0:
            return A, 0.0, 0.0
        if t < 2.0:  # carried
            u = t - 1.0
            pose = (A[0] + u * (B[0] - A[0]), A[1] + u * (B[1] - A[1]), A[2] + u * (B[2] - A[2]))
            return pose, 0.3 * math.sin(math.pi * u), 0.0
        d = v * max(t - 2.3, 0.0)
        pose = (B[0] + d * math.cos(B[2]), B[1] + d * math.sin(B[2]), B[2])
        return pose, 0.0, v if t > 2.3 else 0.0

    loc.set_initial_pose(*A, 0)
    rng = np.random.default_rng(5)
    n = int(seconds)
    events: list[tuple[int, int]] = [(k * 20_000_000, 0) for k in range(1, n * 50)]  # odometry
    events += [(k * 66_666_667, 1) for k in range(1, n * 15)]  # frames
    out: Run = []
    for t_ns, kind in sorted(events):
        pose, lift, speed = truth(t_ns * 1e-9)
        if kind == 0:
            loc.handle(OdometryMeasured(t_ns, speed, speed))
            continue
        T = T_world_body_from_pose(*pose)
        T[2, 3] = lift
        near = np.hypot(P[:, 0] - pose[0], P[:, 1] - pose[1]) <= SEEN_M
        px, ok = predict_pixels(CAM, T, P[near])
        px = px[ok] + rng.normal(0.0, 0.3, (int(ok.sum()), 2))
        est = loc.handle(SpotsObserved(t_ns, px, np.ones(len(px)), np.full(len(px), 9.0)))[0]
        assert isinstance(est, PoseEstimate)
        out.append((t_ns * 1e-9, est.mode, math.hypot(est.x - pose[0], est.y - pose[1])))
    return out


def test_a_kidnapped_robot_is_not_fused_while_carried_and_is_found_again_driving_on() -> None:
    """Carried 2.5 m and turned, put down, driving on towards the skylight."""
    out = _kidnap(_hall(gap=True), (1.2, 1.2, -1.2), (3.6, 2.0, 0.3), 8.0)
    # never a wrong fix: every landmark frame within 3 cm of the truth
    assert max(e for _, mode, e in out if mode == "landmark") < 0.03
    # picked up at 1.0 s: not fused from the next frames on, lost within 1.2 s
    assert not any(mode == "landmark" for t, mode, _ in out if 1.1 < t < 2.0)
    t_lost = next(t for t, mode, _ in out if mode == "lost")
    assert 1.5 < t_lost < 2.3
    # put down at 2.0 s: back (for good) within 5 s of driving on
    t_back = next(t for t, mode, _ in out if t > 2.0 and mode == "landmark")
    assert t_back < 7.0
    assert all(mode == "landmark" for t, mode, _ in out if t > t_back + 0.5)


def test_a_robot_put_down_one_spacing_away_on_a_regular_grid_is_never_taken_for_where_it_was():
    """The classic trap: lifted and put down 40 cm (one spacing) away, same heading, mid-hall
    of the perfect grid. Every view after the put-down is the view from where it was picked
    up (and from its other grid copies): the prior (where it got lost) must not decide, and
    no tracking hand-off may take the old pose back. It says `lost`, never a wrong pose."""
    out = _kidnap(_hall(gap=False), (2.2, 1.8, 0.3), (2.6, 1.8, 0.3), 5.0)
    assert max(e for _, mode, e in out if mode == "landmark") < 0.03
    after = [mode for t, mode, _ in out if t > 2.0]
    assert after and all(mode == "lost" for mode in after)


def test_a_retired_pose_keeps_its_gap_to_the_best_when_asked() -> None:
    """The best's own sum sinks on frames a newborn leads (-6 here); a pose retired 15
    below the best stays 15 below it (`retired_as_gap`), not 9 (its frozen sum)."""
    cfg = RelocalizationConfig(retired_as_gap=True)
    hs = HypothesisSet(cfg)
    hs.poses = np.array([[0.0, 0.0, 0.0], [5.0, 0.0, 0.0]])
    hs.log_lr = np.array([0.0, -15.0])
    hs._retire(hs.poses[1:], hs.log_lr[1:])
    hs.poses, hs.log_lr = hs.poses[:1], np.array([-6.0])  # the best sank since
    assert hs._second(0) == -21.0
    frozen = HypothesisSet(RelocalizationConfig())
    frozen.poses = np.array([[0.0, 0.0, 0.0], [5.0, 0.0, 0.0]])
    frozen.log_lr = np.array([0.0, -15.0])
    frozen._retire(frozen.poses[1:], frozen.log_lr[1:])
    frozen.poses, frozen.log_lr = frozen.poses[:1], np.array([-6.0])
    assert frozen._second(0) == -15.0  # the default: the sum as it was
