"""Identification by geometry: one frame's spots matched to the map as a constellation."""

from __future__ import annotations

import math

import numpy as np
import pytest

from localizer.camera import T_body_camera_upward, predict_pixels
from localizer.constellation import ConstellationConfig, match_constellation, scoring_config
from localizer.geometry import T_world_body_from_pose
from localizer.relocalization import RelocalizationConfig
from localizer.triangles import map_triangles, sorted_sides, spot_triangles, triangle_hypotheses
from tests.localizer.cases import fisheye_camera, irregular_positions

CAM = fisheye_camera(T_body_camera_upward(height=0.3))
CFG = ConstellationConfig()
SIGMA_M = 0.06  # a panel's centroid: survey and diffuser


def panel_grid(nx: int, ny: int, sx: float = 3.0, sy: float = 3.7) -> np.ndarray:
    return np.array([[i * sx, j * sy, 3.0] for i in range(nx) for j in range(ny)])


def seen(positions: np.ndarray, pose: tuple[float, float, float], seed: int = 1) -> np.ndarray:
    """The spots of the lights seen from `pose`, each centroid off by SIGMA_M (fixed per
    light: where the survey put it is not where its blob's centre is)."""
    return seen_rows(positions, pose, seed)[0]


def seen_rows(
    positions: np.ndarray, pose: tuple[float, float, float], seed: int = 1
) -> tuple[np.ndarray, np.ndarray]:
    """`seen`, and the map row of each spot."""
    rng = np.random.default_rng(seed)
    off = np.column_stack([rng.normal(0, SIGMA_M, (len(positions), 2)), np.zeros(len(positions))])
    px, ok = predict_pixels(CAM, T_world_body_from_pose(*pose), positions + off)
    return px[ok], np.flatnonzero(ok)


def match(positions: np.ndarray, spots: np.ndarray, prior=None):  # type: ignore[no-untyped-def]
    index = map_triangles(positions[:, :2], 12.0, CFG.max_map_triangles)
    scoring = scoring_config(RelocalizationConfig(), CFG, SIGMA_M)
    return match_constellation(
        CAM, positions, spots, index, CFG, scoring, landmark_sigma_m=SIGMA_M, prior=prior
    )


def test_triangle_invariant_recovers_a_rigid_motion_exactly() -> None:
    rng = np.random.default_rng(0)
    P = rng.uniform(0, 6, (9, 2))
    x, y, th = 1.3, -0.4, 2.5
    R = np.array([[math.cos(th), -math.sin(th)], [math.sin(th), math.cos(th)]])
    q = (P - [x, y]) @ R  # body points: P = R q + t
    tris = spot_triangles(q, list(range(6)), CFG.min_side_m, CFG.max_spot_triangles)
    index = map_triangles(P, 20.0, 10_000)
    hyps = triangle_hypotheses(q, tris[:1], P, index, 1e-6, 0.0)
    assert len(hyps) == 1  # a mirror image or another order would not agree side by side
    np.testing.assert_allclose(hyps[0], [x, y, th - 2 * math.pi if th > math.pi else th], atol=1e-9)


def test_sorted_sides_are_the_same_for_any_vertex_order() -> None:
    tri = np.array([[[0.0, 0.0], [3.0, 0.0], [0.0, 4.0]]])
    _, key = sorted_sides(tri)
    _, key2 = sorted_sides(tri[:, [2, 0, 1]])
    np.testing.assert_allclose(key, [[3.0, 4.0, 5.0]])
    np.testing.assert_allclose(key2, key)


@pytest.mark.parametrize("truth", [(10.0, 9.0, 0.3), (5.0, 4.0, -2.0), (14.5, 3.0, 3.1)])
def test_cold_start_on_an_irregular_ceiling_is_unique_and_right(
    truth: tuple[float, float, float],
) -> None:
    lights = irregular_positions(np.random.default_rng(3), 0, (20.0, 16.0), spacing=2.5, z=3.0)
    spots, rows = seen_rows(lights, truth)
    m = match(lights, spots)
    assert m.status == "unique", m.reason
    assert m.pose is not None  # (a planar pose on the median ceiling: the fix refines it)
    assert math.hypot(m.pose[0] - truth[0], m.pose[1] - truth[1]) < 0.15
    assert abs(math.remainder(m.pose[2] - truth[2], 2 * math.pi)) < math.radians(3)
    assert len(m.pairs) >= 0.8 * len(spots)
    assert all(rows[s] == r for r, s in m.pairs)  # every spot named right


def test_cold_start_on_a_regular_grid_is_reported_ambiguous_not_guessed() -> None:
    grid = panel_grid(8, 6)
    truth = (10.0, 9.0, 0.3)
    m = match(grid, seen(grid, truth))
    assert m.status == "ambiguous"
    assert not m.pairs
    assert "regular layout" in m.reason and "start pose" in m.reason
    # the truth is among the tied candidates, and so are the poses a cell away
    d = np.hypot(m.candidates[:, 0] - truth[0], m.candidates[:, 1] - truth[1])
    assert d.min() < 0.1 and len(m.candidates) > 10


def test_a_prior_within_half_a_cell_decides_the_regular_grid() -> None:
    grid = panel_grid(8, 6)
    truth = (10.0, 9.0, 0.3)
    prior = ((10.4, 8.7, 0.4), np.diag([0.4**2, 0.4**2, 0.2**2]))
    m = match(grid, seen(grid, truth), prior)
    assert m.status == "unique", m.reason
    assert m.pose is not None and math.hypot(m.pose[0] - 10.0, m.pose[1] - 9.0) < 0.1
    # a prior as wide as a cell cannot: the next cell scores within the margin
    wide = match(grid, seen(grid, truth), ((10.0, 9.0, 0.3), np.diag([1.5**2, 1.5**2, 0.2**2])))
    assert wide.status == "ambiguous"


def test_stray_lights_and_too_few_spots_are_said() -> None:
    lights = irregular_positions(np.random.default_rng(3), 0, (20.0, 16.0), spacing=2.5, z=3.0)
    truth = (10.0, 9.0, 0.3)
    spots = seen(lights, truth)
    stray = np.array([[100.0, 80.0], [500.0, 400.0]])  # two lamps that are not on the map
    m = match(lights, np.vstack([spots, stray]))
    assert m.status == "unique" and m.pose is not None
    assert math.hypot(m.pose[0] - truth[0], m.pose[1] - truth[1]) < 0.15
    assert all(s < len(spots) for _, s in m.pairs)
    few = match(lights, spots[:2])
    assert few.status == "too_few_spots" and "3 or more" in few.reason
    # lights nobody mapped: nothing matches
    elsewhere = irregular_positions(np.random.default_rng(11), 0, (20.0, 16.0), 2.5, z=3.0)
    none = match(lights, seen(elsewhere, truth))
    assert none.status in ("no_match", "ambiguous") and not none.pairs
