"""Keeping the map true (`survey.upkeep`, `survey.upkeep_frame`): known answers on a synthetic
ceiling seen through a miscalibrated wide lens from a robot driving lanes."""

from __future__ import annotations

import math
from typing import Protocol

import numpy as np
import numpy.typing as npt
import pytest

from localizer.camera import CameraModel, T_body_camera_upward, predict_pixels
from localizer.events import PoseEstimate
from localizer.geometry import T_world_body_from_pose
from localizer.pose import solve_pose
from sim.cameras import perturbed_camera, wide_angle_camera
from survey.ceiling import ceiling_points_world
from survey.upkeep import MapUpkeep, UpkeepConfig
from survey.upkeep_frame import frame_evidence, match_spots

NS = 1_000_000_000
CAMERA = wide_angle_camera("fisheye", T_body_camera=T_body_camera_upward(height=0.3))
SIGMA_PX = 0.3


def ceiling(seed: int = 0) -> tuple[list[int], np.ndarray]:
    """A 5 x 4 grid, 1.1 m apart, placed irregularly, 2.5 m +- 3 cm."""
    rng = np.random.default_rng(seed)
    xs, ys = np.meshgrid(np.arange(5) * 1.1, np.arange(4) * 1.1)
    p = np.column_stack([xs.ravel(), ys.ravel(), np.full(xs.size, 2.5)])
    p += rng.uniform(-0.15, 0.15, p.shape) * np.array([1, 1, 0.2])
    return list(range(10, 10 + len(p))), p


def lanes(n: int) -> list[tuple[float, float, float]]:
    """Poses back and forth along three lanes under the grid (10 cm apart)."""
    out = []
    for k in range(n):
        lane, s = divmod(k * 0.1, 4.4)
        y = 0.4 + (lane % 3) * 1.2
        fwd = int(lane) % 2 == 0
        out.append((s if fwd else 4.4 - s, y, 0.0 if fwd else math.pi))
    return out


class Observer(Protocol):
    """`MapUpkeep` or the server's `MapUpkeepService`."""

    def observe(
        self, robot: str, camera: CameraModel, pose: PoseEstimate, pixels: npt.ArrayLike
    ) -> int: ...


def drive(upkeep: Observer, truth: np.ndarray, ids: list[int], frames: int, seed: int = 1) -> None:
    """Frames of a robot whose true camera differs from the nominal one (calibration error);
    each with the localizer's estimate (1 mm, 1 mrad off) using every landmark in view."""
    rng = np.random.default_rng(seed)
    true_cam = perturbed_camera(CAMERA, np.random.default_rng(seed + 100))
    for k, (x, y, th) in enumerate(lanes(frames)):
        px, ok = predict_pixels(true_cam, T_world_body_from_pose(x, y, th), truth)
        ok &= (px[:, 0] > 20) & (px[:, 0] < 620) & (px[:, 1] > 20) & (px[:, 1] < 460)
        seen = tuple(i for i, v in zip(ids, ok, strict=True) if v)
        pixels = px[ok] + rng.normal(0, SIGMA_PX, (int(ok.sum()), 2))
        est = PoseEstimate(
            k * NS // 10, x + rng.normal(0, 1e-3), y + rng.normal(0, 1e-3),
            th + rng.normal(0, 1e-3), np.diag([1e-6, 1e-6, 1e-6]), "landmark", seen, seen,
        )  # fmt: skip
        upkeep.observe("r1", CAMERA, est, pixels)


def test_one_frame_recovers_a_displacement_a_pose_fit_would_hide() -> None:
    """Leave-one-out: a landmark 2 cm off in the map, the others exact. Residuals against
    the pose fitted to all of them show only part of the 2 cm (the pose leans toward the
    wrong one); the frame's evidence, its pose eliminated, gives all of it."""
    ids, p_map = ceiling()
    pose = (2.2, 1.6, 0.3)
    T = T_world_body_from_pose(*pose)
    _, ok = predict_pixels(CAMERA, T, p_map)
    rows = np.flatnonzero(ok)[:5]
    truth = p_map[rows].copy()
    truth[0, :2] += (0.02, 0.0)
    pixels, _ = predict_pixels(CAMERA, T, truth)
    fit = solve_pose(CAMERA, pixels, p_map[rows], initial=pose, pixel_sigma_px=SIGMA_PX)
    assert fit is not None
    on_ceiling, _ = ceiling_points_world(CAMERA, [(fit.x, fit.y, fit.theta)], pixels[:1],
                                         p_map[rows[0], 2])  # fmt: skip
    naive = on_ceiling[0, 0] - p_map[rows[0], 0]
    assert naive < 0.85 * 0.02  # the self-confirmation bias

    ev = frame_evidence(CAMERA, pose, pixels, p_map[rows], [ids[r] for r in rows],
                        lambda u, v: SIGMA_PX)  # fmt: skip
    assert ev is not None and ev.information.shape == (19, 19)
    # prior: the others, every height and the camera known (1 um, 1e-9), landmark 0
    # free in x, y (1 m)
    prior = np.full(19, 1e-6**2)
    prior[[0, 1]] = 1.0
    prior[15:] = 1e-18
    delta = np.linalg.solve(ev.information + np.diag(1 / prior), ev.vector)
    np.testing.assert_allclose(delta[:3], [0.02, 0.0, 0.0], atol=2e-4)
    np.testing.assert_allclose(delta[3:15], 0.0, atol=1e-5)
    assert ev.chi2 > 20  # the frame does not fit the map (2K - 3 = 7 degrees of freedom)


def test_a_moved_landmark_is_proposed_and_no_other() -> None:
    """A replaced tile: one landmark 5 cm from its map position, every other one off by the
    survey's 3 mm. It is proposed as moved within a few mm of where it is; none of the
    others is, over the whole drive."""
    ids, truth = ceiling()
    rng = np.random.default_rng(4)
    p_map = truth + rng.normal(0, 0.003, truth.shape)
    truth = truth.copy()
    truth[7] += (0.03, -0.04, 0.0)
    up = MapUpkeep(UpkeepConfig(map_sigma_m=0.003, settle_s=0.0, view_spacing_m=0.1))
    up.set_map(dict(zip(ids, p_map, strict=True)))
    drive(up, truth, ids, 150)
    props = up.proposals()
    moved = [p for p in props if p.kind == "moved"]
    assert [p.landmark_id for p in moved] == [ids[7]]
    p = moved[0]
    assert np.linalg.norm(np.array(p.proposed) - truth[7]) < 0.004
    assert p.views >= 10 and p.statistic > 30.7
    assert p.old == tuple(p_map[7])
    assert abs(p.shift_m - 0.05) < 0.005


def test_an_unmoved_map_is_refined_not_flagged() -> None:
    """Only the survey's 3 mm error: no landmark is proposed as moved, and the refined
    positions are closer to the truth, relative to each other (what the heading sees),
    than the survey's."""
    ids, truth = ceiling(seed=2)
    rng = np.random.default_rng(5)
    p_map = truth + rng.normal(0, 0.003, truth.shape)
    up = MapUpkeep(UpkeepConfig(map_sigma_m=0.003, settle_s=0.0, view_spacing_m=0.1))
    up.set_map(dict(zip(ids, p_map, strict=True)))
    drive(up, truth, ids, 150, seed=3)
    props = up.proposals()
    assert [p for p in props if p.kind == "moved"] == []
    refined = {p.landmark_id: np.array(p.proposed) for p in props}
    assert len(refined) >= 10
    new = np.array([refined.get(i, p) for i, p in zip(ids, p_map, strict=True)])

    def relative_xy_error(p: np.ndarray) -> float:  # errors with the mean shift removed
        e = (p - truth)[:, :2]
        return float(np.sqrt(np.mean((e - e.mean(axis=0)) ** 2)))

    assert relative_xy_error(new) < 0.8 * relative_xy_error(p_map)
    estimate, _ = up.estimate()  # every landmark, proposed or not
    assert relative_xy_error(estimate) < 0.5 * relative_xy_error(p_map)
    for p in props:  # honest sigmas
        err = np.linalg.norm(np.array(p.proposed) - truth[ids.index(p.landmark_id)])
        assert err < 4 * p.sigma_m + 0.002


def test_map_changes_recentre_the_evidence_and_decisions_drop_it() -> None:
    ids, truth = ceiling()
    p_map = truth.copy()
    truth = truth.copy()
    truth[7] += (0.03, -0.04, 0.0)
    up = MapUpkeep(UpkeepConfig(settle_s=0.0, view_spacing_m=0.1))
    up.set_map(dict(zip(ids, p_map, strict=True)))
    drive(up, truth, ids, 80)
    (p,) = [q for q in up.proposals() if q.kind == "moved"]
    pos_before, _ = up.estimate(frozenset({ids[7]}))
    # staff move it to the proposal: the same evidence, about the new position
    up.set_map({**dict(zip(ids, p_map, strict=True)), ids[7]: p.proposed})
    pos_after, _ = up.estimate(frozenset({ids[7]}))
    np.testing.assert_allclose(pos_after, pos_before, atol=1e-6)  # (its free prior moved)
    assert [q.landmark_id for q in up.proposals() if q.kind == "moved"] == []
    up.accepted(ids[7], p.sigma_m)
    assert up.views(ids[7]) == 0
    up.rejected(ids[8])
    assert up.views(ids[8]) == 0
    with pytest.raises(KeyError, match="landmark 999"):
        up.rejected(999)


def test_frames_that_do_not_count() -> None:
    ids, p = ceiling()
    up = MapUpkeep(UpkeepConfig(settle_s=2.0))
    up.set_map(dict(zip(ids, p, strict=True)))
    cov = np.diag([1e-6, 1e-6, 1e-6])
    px, ok = predict_pixels(CAMERA, T_world_body_from_pose(2.2, 1.6, 0.0), p)
    px = px[ok]
    seen = tuple(ids)
    assert not up.wants("r1", PoseEstimate(0, 2.2, 1.6, 0.0, cov, "landmark", seen, seen))
    # 1 s later: not settled yet; then dead reckoning; then a wide covariance
    assert not up.wants("r1", PoseEstimate(NS, 2.2, 1.6, 0.0, cov, "landmark", seen, seen))
    assert not up.wants("r1", PoseEstimate(3 * NS, 2.2, 1.6, 0.0, cov, "dead_reckoning"))
    wide = np.diag([0.01, 0.01, 1e-4])
    assert not up.wants("r1", PoseEstimate(3 * NS, 2.2, 1.6, 0.0, wide, "landmark", seen, seen))
    good = PoseEstimate(3 * NS, 2.2, 1.6, 0.0, cov, "landmark", seen, seen)
    assert up.observe("r1", CAMERA, good, px) >= 5
    # the same place again does not count (views_spacing_m); lost restarts the settling
    assert up.observe("r1", CAMERA, good, px) == 0
    up.wants("r1", PoseEstimate(4 * NS, 2.2, 1.6, 0.0, cov, "lost"))
    far = PoseEstimate(5 * NS, 3.0, 1.6, 0.0, cov, "landmark", seen, seen)
    assert not up.wants("r1", far)


def test_spots_beside_a_landmark_are_not_matched() -> None:
    """A glint 10 cm beside a landmark's spot makes that landmark ambiguous; a spot midway
    between two landmarks matches neither, and leaves them matched (those in view)."""
    _, p = ceiling()
    pose = (2.2, 1.6, 0.0)
    T = T_world_body_from_pose(*pose)
    extra = np.array([p[6] + (0.1, 0, 0), (p[8] + p[9]) / 2])
    pts = np.vstack([p, extra])
    px, ok = predict_pixels(CAMERA, T, pts)
    pairs = match_spots(CAMERA, pose, px[ok], p, gate_m=0.15, isolation_m=0.3)
    matched = {j for j, _ in pairs}
    assert 6 not in matched and 8 in matched
    assert int(ok.sum()) - 1 not in {s for _, s in pairs}  # the midway spot
    assert len(pairs) == int(ok[: len(p)].sum()) - 1


def test_config_is_checked() -> None:
    with pytest.raises(ValueError, match=r"UpkeepConfig\.gate_m"):
        UpkeepConfig(gate_m=0.0)
    with pytest.raises(ValueError, match="chi2_threshold"):
        UpkeepConfig(chi2_threshold=math.nan)
