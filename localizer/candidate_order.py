"""Which landmarks to probe next, from one sighting and the odometry since (Sec. III-A).

One landmark L identified at pixel p at time t1 puts the robot on a circle around L: the
pixel's ray meets the ceiling at q (body frame, at L's height), so at t1 the body was at
P_L - R(theta) q for an unknown heading theta. The odometry since t1 is the body's motion in
its own frame (d, dtheta), known; so now the body is at

    x(theta) = P_L + R(theta) (d - q),   heading theta + dtheta.

For sampled headings, the camera model says which landmarks would be inside the part of the
image where identification takes evidence (`inner_radius_px` around the principal point);
the candidates are ordered by the fraction of headings in which each is in view, ties (and
the never-visible ones) by distance from L. A robot that saw L and drove on probes the
landmarks it can see now, not those that were beside L. "Now" is when the probe lands: the
owner extrapolates the odometry over the command latency (`ProbePlan.latency_s`, measured)
and the frames a probe needs, so that a fast robot, or a slow radio, probes what will be in
view rather than what was.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from localizer.camera import CameraModel, pixels_from_points_camera
from localizer.first_fix import OdometryPose, body_motion
from localizer.geometry import wrap_angle
from localizer.handoff import ceiling_points_body
from localizer.identification import Sighting
from localizer.types import FloatArray


def view_fractions(
    camera: CameraModel,
    anchor_position: FloatArray,
    anchor_pixel: tuple[float, float],
    motion: tuple[FloatArray, float],
    positions: FloatArray,
    *,
    headings: int,
    inner_radius_px: float,
) -> FloatArray:
    """For each landmark, the fraction of headings in which it is in view now.

    Args:
        anchor_position: the identified landmark's map position, shape (3,).
        anchor_pixel: where it was seen (col, row).
        motion: the body's motion since, in the body frame then: (d (2,), dtheta), metres
            and radians (`body_motion`).
        positions: the candidates' map positions, shape (N, 3).
        headings: number of headings sampled over the circle.
        inner_radius_px: in view means within this of the principal point, pixels.

    Returns:
        Shape (N,), in [0, 1].
    """
    P = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    if len(P) == 0:
        return np.zeros(0)
    q = ceiling_points_body(
        camera, np.array([anchor_pixel], dtype=np.float64), np.array([anchor_position[2]])
    )[0]
    d, dth = motion
    th = np.linspace(-np.pi, np.pi, headings, endpoint=False)
    c, s = np.cos(th), np.sin(th)
    v = np.asarray(d, dtype=np.float64) - q
    x = anchor_position[0] + c * v[0] - s * v[1]  # (H,)
    y = anchor_position[1] + s * v[0] + c * v[1]
    cn, sn = np.cos(th + dth), np.sin(th + dth)
    dx = P[None, :, 0] - x[:, None]  # (H, N)
    dy = P[None, :, 1] - y[:, None]
    bx = cn[:, None] * dx + sn[:, None] * dy
    by = cn[:, None] * dy - sn[:, None] * dx
    p_body = np.stack([bx, by, np.broadcast_to(P[None, :, 2], bx.shape)], axis=-1)
    T = camera.T_body_camera
    p_cam = (p_body.reshape(-1, 3) - T[:3, 3]) @ T[:3, :3]  # camera from body
    px, valid = pixels_from_points_camera(camera, p_cam)
    inner = np.hypot(px[:, 0] - camera.cu, px[:, 1] - camera.cv) <= inner_radius_px
    seen = (valid & inner).reshape(len(th), len(P))
    fractions: FloatArray = seen.mean(axis=0)
    return fractions


def order_by_view(
    camera: CameraModel,
    ids: Sequence[int],
    positions: FloatArray,
    anchor_id: int,
    anchor_pixel: tuple[float, float],
    odo_then: OdometryPose,
    odo_now: OdometryPose,
    *,
    headings: int,
    inner_radius_px: float,
) -> list[tuple[int, float]]:
    """The landmark IDs (all but the anchor) with the fraction of headings in which each is
    in view at `odo_now`, ordered by it, most first; ties by distance from the anchor.

    Args:
        ids: the map's landmark IDs; positions: theirs, shape (N, 3).
        anchor_id: the identified landmark, seen at `anchor_pixel` when the raw odometry
            read `odo_then`; `odo_now`: the raw odometry when the probe lands (any time
            after; the sighting's age does not matter).
    """
    P = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    anchor = P[list(ids).index(anchor_id)]
    others = [k for k, i in enumerate(ids) if i != anchor_id]
    frac = view_fractions(
        camera,
        anchor,
        anchor_pixel,
        body_motion(odo_then, odo_now),
        P[others],
        headings=headings,
        inner_radius_px=inner_radius_px,
    )
    dist = np.hypot(P[others, 0] - anchor[0], P[others, 1] - anchor[1])
    rank = np.lexsort((dist, -frac))
    return [(int(ids[others[k]]), float(frac[k])) for k in rank]


class ViewOrdering:
    """When to order the candidates again by view, and which came into view since.

    The order from one anchor (a sighting) is made again once the odometry has moved
    `reorder_distance_m` or turned `reorder_turn_rad` since it was last made; candidates in
    view (at some heading) now but not then have come into view (a probe of them earlier
    in the round was void).
    """

    def __init__(self, reorder_distance_m: float, reorder_turn_rad: float) -> None:
        self.reorder_distance_m = reorder_distance_m
        self.reorder_turn_rad = reorder_turn_rad
        self.reset()

    def reset(self) -> None:
        """Forget the last ordering (a new identification, or a new anchor)."""
        self._last: tuple[tuple[int, int], OdometryPose] | None = None
        self._in_view: set[int] = set()

    def due(self, anchor: Sighting, odo_now: OdometryPose) -> bool:
        """Whether to order again: a new anchor, or the robot moved or turned enough."""
        if self._last is None or self._last[0] != (anchor.landmark_id, anchor.t_ns):
            return True
        last = self._last[1]
        moved = float(np.hypot(odo_now[0] - last[0], odo_now[1] - last[1]))
        turned = abs(float(wrap_angle(odo_now[2] - last[2])))
        return moved >= self.reorder_distance_m or turned >= self.reorder_turn_rad

    def ordered(
        self, anchor: Sighting, odo_now: OdometryPose, order: list[tuple[int, float]]
    ) -> tuple[list[int], set[int]]:
        """Note an ordering made now (`order_by_view`'s); returns the IDs in order and
        those that came into view since the last ordering from the same anchor."""
        key = (anchor.landmark_id, anchor.t_ns)
        same = self._last is not None and self._last[0] == key
        in_view = {i for i, f in order if f > 0}
        fresh = in_view - self._in_view if same else set()
        self._last, self._in_view = (key, odo_now), in_view
        return [i for i, _ in order], fresh
