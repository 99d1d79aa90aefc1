"""Search windows and the bottleneck (min-max) assignment of Sec. IV-A.1."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from localizer.tracking import (
    TrackingConfig,
    bottleneck_assignment,
    default_angular_speed,
    motion_bound_px,
    scale_px_per_m,
    unambiguous_pairs,
    window_half_sizes,
)


def test_fig_8b_two_landmarks_never_take_the_same_spot() -> None:
    # Nearest neighbour would give spot 0 to both landmarks.
    cost = np.array([[1.0, 9.0], [2.0, 3.0]])
    assert bottleneck_assignment(cost, 10.0) == [(0, 0), (1, 1)]


def test_minimises_the_largest_displacement_not_the_sum() -> None:
    # Sum-optimal: (0,0)+(1,1) = 0 + 10 = 10; min-max: (0,1)+(1,0) = 6 + 6 = 12, max 6.
    cost = np.array([[0.0, 6.0], [6.0, 10.0]])
    assert bottleneck_assignment(cost, 20.0) == [(0, 1), (1, 0)]


def test_gate_excludes_far_spots_and_keeps_most_pairs() -> None:
    cost = np.array([[1.0, 50.0], [40.0, 60.0]])
    assert bottleneck_assignment(cost, np.array([5.0, 5.0])) == [(0, 0)]
    assert bottleneck_assignment(np.zeros((0, 3)), 1.0) == []
    assert bottleneck_assignment(np.full((2, 2), 9.0), 1.0) == []


@pytest.mark.parametrize("seed", range(20))
def test_matches_brute_force_for_random_costs(seed: int) -> None:
    rng = np.random.default_rng(seed)
    m, n = int(rng.integers(1, 5)), int(rng.integers(1, 6))
    cost = rng.uniform(0, 10, size=(m, n))
    gate = 7.0
    pairs = bottleneck_assignment(cost, gate)
    assert len({c for _, c in pairs}) == len(pairs)
    best = (0, -np.inf)
    for perm in itertools.permutations(range(max(m, n)), m):
        chosen = [(r, c) for r, c in enumerate(perm) if c < n and cost[r, c] <= gate]
        key = (len(chosen), -max((cost[r, c] for r, c in chosen), default=0.0))
        best = max(best, key)
    got = (len(pairs), -max((cost[r, c] for r, c in pairs), default=0.0))
    assert got == pytest.approx(best)


def test_window_size_grows_with_speed_interval_radius_and_uncertainty() -> None:
    cfg = TrackingConfig()
    scale = scale_px_per_m(300.0, 2.2)
    w = default_angular_speed(1.0, 0.36)
    assert w == pytest.approx(2.0 / 0.36)
    radial = np.array([0.0, 200.0])
    bound = motion_bound_px(
        radial, max_speed_m_s=1.0, max_angular_speed_rad_s=w, dt_s=1 / 30, scale_px_per_m=scale
    )
    np.testing.assert_allclose(bound, [scale / 30, scale / 30 + w / 30 * 200])
    half = window_half_sizes(
        radial,
        np.array([0.5, 0.5]),
        config=cfg,
        max_speed_m_s=1.0,
        max_angular_speed_rad_s=w,
        dt_unpredicted_s=1 / 30,
        scale_px_per_m=scale,
    )
    np.testing.assert_allclose(half[:, 0], cfg.min_half_size_px + cfg.sigma_gate * 0.5 + bound)
    np.testing.assert_allclose(half[:, 0], half[:, 1])


def test_config_is_validated() -> None:
    with pytest.raises(ValueError):
        TrackingConfig(min_half_size_px=0.0)


def test_a_free_spot_nearly_as_close_makes_the_pair_ambiguous() -> None:
    # landmark 0: its spot 2 px off, a glint (spot 2) 5 px off; landmark 1: alone, 3 px off.
    # With sigma 3 px: (25 - 4) / (2 * 9) = 1.2 nats < 4.6: landmark 0 is left out.
    cost = [[2.0, 40.0, 5.0], [50.0, 3.0, 45.0]]
    pairs = bottleneck_assignment(cost, [12.0, 12.0])
    assert pairs == [(0, 0), (1, 1)]
    keep, left = unambiguous_pairs(cost, pairs, [3.0, 3.0], 4.6)
    assert keep == [(1, 1)] and left == [0]
    # the glint 12 px off: (144 - 4) / 18 = 7.8 nats, clearly the landmark's spot
    cost[0][2] = 12.0
    assert unambiguous_pairs(cost, pairs, [3.0, 3.0], 4.6) == (pairs, [])


def test_a_neighbour_landmarks_spot_is_never_a_rival() -> None:
    # a dense grid: landmark 1's spot is 4 px from landmark 0's prediction, but it is taken
    cost = [[1.0, 4.0], [4.0, 1.0]]
    pairs = bottleneck_assignment(cost, 10.0)
    assert unambiguous_pairs(cost, pairs, [3.0, 3.0], 4.6) == (pairs, [])
