"""Where to drive next during a survey: waypoints over what is still uncertain or unseen.

Pure (numpy in, numpy out). The live survey (`live.survey.service`) calls it after each
estimate with the landmarks' current positions and uncertainties, the site's extent, where the
robot has been and where it is; the viewer draws the result as a polyline.

The route is greedy: from the robot, the next waypoint is the goal with the largest
uncertainty per distance (`weight / (1 + distance / distance_scale_m)`); every goal the leg to
it passes within `view_radius_m` of is taken as seen on the way and dropped; repeat. The goals:

- each landmark whose 1-sigma uncertainty exceeds `done_sigma_m` (a landmark never identified,
  at its rough position, weighs `unseen_sigma_m`);
- while some landmarks have no position at all, the centres of a grid of cells
  `lane_spacing_m` apart over the site that the robot has not yet passed within
  `view_radius_m` of (weight `unseen_sigma_m`): nearest first, they make lanes one camera
  footprint apart.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from localizer.types import FloatArray


@dataclass(frozen=True)
class RouteConfig:
    """Tuning of the suggested route (metres).

    Attributes:
        view_radius_m: a landmark this close (horizontally) to the robot's path is seen well
            enough to count as visited (well inside the camera's footprint on the ceiling).
        lane_spacing_m: cells of the site not yet covered are this far apart (lanes one
            footprint apart).
        done_sigma_m: a landmark at or under this 1-sigma uncertainty needs no more views.
        unseen_sigma_m: the weight of a landmark never identified and of a cell not covered.
        distance_scale_m: a goal this far away counts half as much as one at the robot.
        max_waypoints: the route is cut after this many waypoints.
    """

    view_radius_m: float = 0.8
    lane_spacing_m: float = 1.6
    done_sigma_m: float = 0.005
    unseen_sigma_m: float = 0.3
    distance_scale_m: float = 2.0
    max_waypoints: int = 12

    def __post_init__(self) -> None:
        for name in ("view_radius_m", "lane_spacing_m", "done_sigma_m", "distance_scale_m"):
            if not getattr(self, name) > 0:
                raise ValueError(f"RouteConfig: {name} must be > 0, got {getattr(self, name)}")
        if self.max_waypoints < 1:
            raise ValueError(f"RouteConfig: max_waypoints must be >= 1, got {self.max_waypoints}")


def segment_distances(points: FloatArray, a: FloatArray, b: FloatArray) -> FloatArray:
    """Distance of each point (N, 2) from the segment a-b (2,), metres."""
    ab = b - a
    length2 = float(ab @ ab)
    if length2 == 0.0:
        return np.asarray(np.hypot(*(points - a).T), dtype=np.float64)
    s = np.clip((points - a) @ ab / length2, 0.0, 1.0)
    closest = a + s[:, None] * ab
    return np.asarray(np.hypot(*(points - closest).T), dtype=np.float64)


def uncovered_cells(
    extent: tuple[float, float, float, float],
    visited_xy: npt.ArrayLike,
    config: RouteConfig,
) -> FloatArray:
    """Centres (M, 2) of the cells `lane_spacing_m` apart over `extent` (x0, x1, y0, y1) that
    no visited point (K, 2) came within `view_radius_m` of."""
    x0, x1, y0, y1 = extent
    step = config.lane_spacing_m
    nx = max(1, round((x1 - x0) / step))
    ny = max(1, round((y1 - y0) / step))
    xs = x0 + (np.arange(nx) + 0.5) * (x1 - x0) / nx
    ys = y0 + (np.arange(ny) + 0.5) * (y1 - y0) / ny
    cells = np.stack(np.meshgrid(xs, ys), axis=-1).reshape(-1, 2)
    seen = np.asarray(visited_xy, dtype=np.float64).reshape(-1, 2)
    if len(seen) == 0:
        return cells
    d = np.hypot(cells[:, None, 0] - seen[None, :, 0], cells[:, None, 1] - seen[None, :, 1])
    return np.asarray(cells[d.min(axis=1) > config.view_radius_m], dtype=np.float64)


def suggest_route(
    robot_xy: npt.ArrayLike,
    landmarks_xy: npt.ArrayLike,
    sigma_m: npt.ArrayLike,
    extent: tuple[float, float, float, float],
    *,
    visited_xy: npt.ArrayLike = (),
    unplaced: int = 0,
    config: RouteConfig | None = None,
) -> FloatArray:
    """Waypoints (M, 2) from the robot over what is still uncertain, in driving order.

    Args:
        robot_xy: where the robot is (2,), metres.
        landmarks_xy: the landmarks' current horizontal positions (N, 2) (estimates, or the
            rough positions of those never identified), metres.
        sigma_m: their 1-sigma uncertainties (N,), metres; NaN for a landmark never
            identified (it weighs `unseen_sigma_m`).
        extent: the site, (x0, x1, y0, y1) metres; waypoints stay inside it.
        visited_xy: where the robot has been (K, 2), metres (for the cells still uncovered).
        unplaced: landmarks with no position at all: while any, the uncovered cells are goals.
        config: tuning.

    Returns:
        (M, 2) waypoints, M <= `max_waypoints`; empty when nothing is left to see.
    """
    cfg = config or RouteConfig()
    x0, x1, y0, y1 = extent
    if not (x1 > x0 and y1 > y0):
        raise ValueError(f"suggest_route: extent (x0, x1, y0, y1) must not be empty, got {extent}")
    pos = np.asarray(landmarks_xy, dtype=np.float64).reshape(-1, 2)
    sig = np.asarray(sigma_m, dtype=np.float64).reshape(-1)
    if len(sig) != len(pos):
        raise ValueError(f"suggest_route: {len(pos)} landmarks but {len(sig)} sigmas")
    weight = np.where(np.isnan(sig), cfg.unseen_sigma_m, sig)
    keep = weight > cfg.done_sigma_m
    goals, weights = pos[keep], weight[keep]
    if unplaced > 0:
        cells = uncovered_cells(extent, visited_xy, cfg)
        goals = np.vstack([goals, cells])
        weights = np.concatenate([weights, np.full(len(cells), cfg.unseen_sigma_m)])
    goals = np.column_stack([np.clip(goals[:, 0], x0, x1), np.clip(goals[:, 1], y0, y1)])
    here = np.asarray(robot_xy, dtype=np.float64).reshape(2)
    # goals already within view of the robot are being seen now
    left = np.hypot(*(goals - here).T) > cfg.view_radius_m
    route: list[FloatArray] = []
    while left.any() and len(route) < cfg.max_waypoints:
        idx = np.flatnonzero(left)
        d = np.hypot(*(goals[idx] - here).T)
        best = idx[int(np.argmax(weights[idx] / (1.0 + d / cfg.distance_scale_m)))]
        nxt = goals[best]
        left &= segment_distances(goals, here, nxt) > cfg.view_radius_m
        left[best] = False
        route.append(nxt)
        here = nxt
    return np.asarray(route, dtype=np.float64).reshape(-1, 2)
