"""The suggested survey route (`survey.route`): known answers on small floors."""

from __future__ import annotations

import numpy as np
import pytest

from survey.route import RouteConfig, segment_distances, suggest_route, uncovered_cells

SITE = (0.0, 10.0, 0.0, 8.0)
CFG = RouteConfig(view_radius_m=0.5, lane_spacing_m=2.0, distance_scale_m=2.0)


def test_nothing_uncertain_nothing_to_drive() -> None:
    xy = [[1.0, 1.0], [5.0, 5.0]]
    assert suggest_route((0, 0), xy, [0.001, 0.004], SITE, config=CFG).shape == (0, 2)
    assert suggest_route((0, 0), np.zeros((0, 2)), [], SITE, config=CFG).shape == (0, 2)


def test_one_uncertain_landmark_is_the_one_waypoint() -> None:
    route = suggest_route((0, 0), [[1, 1], [5, 0]], [0.001, 0.02], SITE, config=CFG)
    np.testing.assert_allclose(route, [[5.0, 0.0]])


def test_largest_uncertainty_per_distance_first_and_what_is_passed_is_dropped() -> None:
    # near (2, 0): 0.01 / (1 + 2/2) = 0.005; far (4, 0.2): 0.3 / (1 + 4/2) = 0.1 -> far
    # first, and the leg to it passes 0.1 m from (2, 0): seen on the way
    route = suggest_route((0, 0), [[2, 0.1], [4, 0.2]], [0.01, np.nan], SITE, config=CFG)
    np.testing.assert_allclose(route, [[4.0, 0.2]])
    # off the leg (1.5 m away) it stays a goal, visited after
    route = suggest_route((0, 0), [[2, 1.5], [4, 0.2]], [0.01, np.nan], SITE, config=CFG)
    np.testing.assert_allclose(route, [[4.0, 0.2], [2.0, 1.5]])


def test_goals_in_view_now_and_outside_the_site() -> None:
    # (0.3, 0) is in view of the robot already; (12, 3) is clipped to the site's edge
    route = suggest_route((0, 0), [[0.3, 0], [12, 3]], [0.1, 0.1], SITE, config=CFG)
    np.testing.assert_allclose(route, [[10.0, 3.0]])


def test_unplaced_landmarks_cover_the_site_in_lanes_one_footprint_apart() -> None:
    site = (0.0, 8.0, 0.0, 4.0)
    cells = uncovered_cells(site, [], CFG)
    assert cells.shape == (8, 2)  # 4 x 2 cells of 2 m
    np.testing.assert_allclose(sorted(set(cells[:, 0])), [1, 3, 5, 7])
    np.testing.assert_allclose(sorted(set(cells[:, 1])), [1, 3])
    route = suggest_route((0, 0), np.zeros((0, 2)), [], site, unplaced=3, config=CFG)
    # nearest first from the corner: along the lower lane, then back along the upper one
    np.testing.assert_allclose(route, [[1, 1], [3, 1], [5, 1], [7, 1], [7, 3], [5, 3], [3, 3],
                                       [1, 3]])  # fmt: skip
    # the lower lane driven already: only the upper one is left
    visited = np.column_stack([np.linspace(0, 8, 50), np.full(50, 1.2)])
    route = suggest_route((8, 1), np.zeros((0, 2)), [], site, visited_xy=visited, unplaced=1,
                          config=CFG)  # fmt: skip
    np.testing.assert_allclose(route, [[7, 3], [5, 3], [3, 3], [1, 3]])


def test_segment_distances_and_bad_input() -> None:
    d = segment_distances(np.array([[0, 1.0], [3, 0], [-1, 0]]), np.zeros(2), np.array([2.0, 0]))
    np.testing.assert_allclose(d, [1.0, 1.0, 1.0])
    with pytest.raises(ValueError, match="extent"):
        suggest_route((0, 0), [[1, 1]], [0.1], (1.0, 1.0, 0.0, 2.0))
    with pytest.raises(ValueError, match="1 landmarks but 2 sigmas"):
        suggest_route((0, 0), [[1, 1]], [0.1, 0.2], SITE)
    with pytest.raises(ValueError, match="view_radius_m"):
        RouteConfig(view_radius_m=0.0)


def test_the_route_is_cut_at_max_waypoints() -> None:
    xy = np.column_stack([np.arange(1, 10, dtype=float), np.zeros(9)])
    xy[::2, 1] = 3.0  # zig-zag: nothing is passed on the way
    route = suggest_route((0, 0), xy, np.full(9, 0.1), SITE, config=RouteConfig(max_waypoints=4))
    assert route.shape == (4, 2)
