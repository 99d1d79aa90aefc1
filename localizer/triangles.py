"""Triangles of points on the ceiling: the invariant of identification by geometry.

A rigid motion of the plane keeps a triangle's side lengths, and the sign of its area (no
mirror image). `map_triangles` indexes the map's triangles by their sorted sides;
`spot_triangles` forms the spots' triangles; `triangle_hypotheses` registers each spot
triangle onto every map triangle of the same sides (2D Kabsch), in each cyclic vertex order
whose sides agree. Used by `constellation.match_constellation`.
"""

from __future__ import annotations

import itertools
import math
from typing import NamedTuple

import numpy as np
from scipy.spatial import cKDTree

from localizer.hypothesis_scoring import refine_hypotheses
from localizer.types import FloatArray, IntArray


class MapTriangles(NamedTuple):
    """The map's triangles with every side at most `max_side_m`.

    Attributes:
        vertices: landmark rows, counter-clockwise, shape (T, 3).
        sides: side lengths opposite each vertex, shape (T, 3), metres.
        tree: k-d tree of each triangle's sorted sides (the invariant).
        max_side_m: the longest side indexed, metres.
    """

    vertices: IntArray
    sides: FloatArray
    tree: cKDTree
    max_side_m: float


def sorted_sides(points: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Side lengths of triangles, the side opposite each vertex, and their sorted copy.

    Args:
        points: the triangles' corners (x, y), shape (T, 3, 2).

    Returns:
        (sides opposite vertex 0, 1, 2, shape (T, 3); sorted ascending, shape (T, 3)).
    """
    a = np.linalg.norm(points[:, 2] - points[:, 1], axis=1)
    b = np.linalg.norm(points[:, 0] - points[:, 2], axis=1)
    c = np.linalg.norm(points[:, 1] - points[:, 0], axis=1)
    sides = np.column_stack([a, b, c])
    return sides, np.sort(sides, axis=1)


def counter_clockwise(points: FloatArray, vertices: IntArray) -> IntArray:
    """The triangles' vertex rows reordered counter-clockwise (positive signed area).

    Args:
        points: (x, y), shape (N, 2); vertices: rows into `points`, shape (T, 3).
    """
    p = points[vertices]
    cross = (p[:, 1, 0] - p[:, 0, 0]) * (p[:, 2, 1] - p[:, 0, 1]) - (p[:, 1, 1] - p[:, 0, 1]) * (
        p[:, 2, 0] - p[:, 0, 0]
    )
    out = vertices.copy()
    flip = cross < 0
    out[flip, 1], out[flip, 2] = vertices[flip, 2], vertices[flip, 1]
    return out


def map_triangles(positions_xy: FloatArray, max_side_m: float, limit: int) -> MapTriangles:
    """Every triangle of landmarks whose sides are all at most `max_side_m` (at most
    `limit`: when there are more, the longest side allowed shrinks until they fit).

    Args:
        positions_xy: landmark positions (x, y), shape (N, 2).
    """
    tree = cKDTree(positions_xy)
    side = max_side_m
    while True:
        pairs = tree.query_pairs(side, output_type="ndarray")
        neighbours: list[list[int]] = [[] for _ in range(len(positions_xy))]
        for i, j in pairs.tolist():
            neighbours[min(i, j)].append(max(i, j))
        count = sum(len(n) * (len(n) - 1) // 2 for n in neighbours)
        if count <= limit or side < 0.05:
            break
        side *= math.sqrt(limit / count)
    near = {(int(i), int(j)) for i, j in pairs.tolist()} | {
        (int(j), int(i)) for i, j in pairs.tolist()
    }
    tris = [
        (i, j, k)
        for i, ns in enumerate(neighbours)
        for a, j in enumerate(ns)
        for k in ns[a + 1 :]
        if (j, k) in near
    ]
    vertices = np.array(tris, dtype=np.int64).reshape(-1, 3)
    if len(vertices):
        vertices = counter_clockwise(positions_xy, vertices)
    sides, key = sorted_sides(positions_xy[vertices].reshape(-1, 3, 2))
    return MapTriangles(vertices, sides, cKDTree(key.reshape(-1, 3)), float(side))


def spot_triangles(q: FloatArray, anchors: list[int], min_side_m: float, limit: int) -> IntArray:
    """Counter-clockwise triangles of anchor spots (indices into `q`, shape (T, 3)) with
    every side at least `min_side_m`, the largest (by shortest side) first, at most
    `limit`.

    Args:
        q: the spots' ceiling points, body frame, shape (S, 2).
        anchors: the spots to form them from.
    """
    a = np.array(anchors, dtype=np.int64)
    if len(a) < 3:
        return np.zeros((0, 3), dtype=np.int64)
    tris = np.array(list(itertools.combinations(a.tolist(), 3)), dtype=np.int64)
    _, key = sorted_sides(q[tris])
    keep = key[:, 0] >= min_side_m
    tris, key = tris[keep], key[keep]
    order = np.argsort(-key[:, 0], kind="stable")[:limit]
    return counter_clockwise(q, tris[order])


def triangle_hypotheses(
    q: FloatArray,
    tris: IntArray,
    positions_xy: FloatArray,
    index: MapTriangles,
    tolerance_m: float,
    tolerance_frac: float,
) -> FloatArray:
    """Planar poses (x, y, theta), shape (H, 3): every spot triangle registered onto every
    map triangle of the same sides, in each cyclic vertex order whose sides agree.

    Args:
        q: the spots' ceiling points, body frame, shape (S, 2).
        tris: spot triangles (counter-clockwise indices into `q`), shape (T, 3).
        positions_xy: landmarks (x, y), shape (N, 2); `index` their triangles.
        tolerance_m: a side agrees within this (times sqrt 2: two points' errors), plus
            `tolerance_frac` of its length.
    """
    if not len(tris) or not len(index.vertices):
        return np.zeros((0, 3))
    spot_sides, spot_key = sorted_sides(q[tris])
    tol = math.sqrt(2.0) * tolerance_m + tolerance_frac * spot_key[:, 2]
    found = index.tree.query_ball_point(spot_key, r=math.sqrt(3.0) * tol)
    out = []
    for t, rows in enumerate(found):
        if not rows:
            continue
        m = np.asarray(rows, dtype=np.int64)
        for shift in range(3):  # map vertex (v + shift) shows spot vertex v
            order = (np.arange(3) + shift) % 3
            agree = np.all(np.abs(index.sides[m][:, order] - spot_sides[t]) <= tol[t], axis=1)
            if not np.any(agree):
                continue
            rows_v = index.vertices[m[agree]][:, order]  # (M, 3) landmark row per spot vertex
            ones = np.ones((len(rows_v), 3), dtype=np.int64)
            zeros = np.zeros((len(rows_v), 3))
            out.append(refine_hypotheses(zeros, q[tris[t]], positions_xy, rows_v, ones))
    return np.vstack(out) if out else np.zeros((0, 3))


__all__ = [
    "MapTriangles",
    "counter_clockwise",
    "map_triangles",
    "sorted_sides",
    "spot_triangles",
    "triangle_hypotheses",
]
