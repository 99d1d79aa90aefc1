"""Candidate order from one sighting and the odometry since (localizer/candidate_order.py),
and the identifier keeping the newest of inconsistent sightings."""

from __future__ import annotations

import math

import numpy as np

from localizer.camera import predict_pixels
from localizer.candidate_order import order_by_view, view_fractions
from localizer.geometry import T_world_body_from_pose
from localizer.identification import IdentificationConfig, Identifier, Sighting
from tests.localizer.cameras import make_camera
from tests.localizer.cases import grid_positions

MS = 1_000_000
INNER_PX = 0.8 * 238.7


def _in_view(camera, pose, P) -> np.ndarray:  # type: ignore[no-untyped-def]
    px, ok = predict_pixels(camera, T_world_body_from_pose(*pose), P)
    return ok & (np.hypot(px[:, 0] - camera.cu, px[:, 1] - camera.cv) <= INNER_PX)


def test_after_driving_3_m_the_landmarks_in_view_now_come_first() -> None:
    camera = make_camera("radial-tangential", "offset-yaw90")
    P = grid_positions(12, 12, 1.0)  # 11 m x 11 m, 1 m apart
    ids = list(range(100, 100 + len(P)))
    then = (4.3, 4.2, 0.4)  # true pose at the sighting, unknown to the order
    anchor = int(np.argmin(np.hypot(P[:, 0] - 4.0, P[:, 1] - 4.0)))
    px, ok = predict_pixels(camera, T_world_body_from_pose(*then), P[anchor : anchor + 1])
    assert ok[0]
    # The robot drives 3 m straight on and turns 0.5 rad; odometry in its own frame.
    odo_then, odo_now = (10.0, -2.0, 1.0), (10.0 + 3 * math.cos(1.0), -2.0 + 3 * math.sin(1.0), 1.5)
    now = (then[0] + 3 * math.cos(0.4), then[1] + 3 * math.sin(0.4), 0.9)
    visible = {ids[k] for k in np.flatnonzero(_in_view(camera, now, P))}
    assert len(visible) >= 3
    ranked = order_by_view(
        camera, ids, P, ids[anchor], (float(px[0, 0]), float(px[0, 1])), odo_then, odo_now,
        headings=72, inner_radius_px=INNER_PX,
    )  # fmt: skip
    order = [i for i, _ in ranked]
    assert sorted(order) == sorted(set(ids) - {ids[anchor]})
    rank = {lid: k for k, lid in enumerate(order)}
    # The anchor's neighbours (the old order's first) are out of view from anywhere on the
    # circle of radius ~3 m: every landmark in view now comes before all of them.
    near = [ids[k] for k in np.flatnonzero(np.hypot(*(P[:, :2] - P[anchor, :2]).T) < 1.1)]
    near.remove(ids[anchor])
    assert max(rank[v] for v in visible) < min(rank[n] for n in near)
    # Ordered by distance from the anchor (the old order), they came far later.
    by_distance = sorted(
        order, key=lambda i: float(np.hypot(*(P[ids.index(i), :2] - P[anchor, :2])))
    )
    old = {lid: k for k, lid in enumerate(by_distance)}
    assert np.median([rank[v] for v in visible]) < len(order) / 6
    assert np.mean([rank[v] for v in visible]) < 0.75 * np.mean([old[v] for v in visible])
    frac = view_fractions(
        camera, P[anchor], (float(px[0, 0]), float(px[0, 1])),
        (np.array([3.0, 0.0]), 0.5), P, headings=72, inner_radius_px=INNER_PX,
    )  # fmt: skip
    assert all(frac[ids.index(v)] > 0 for v in visible)
    assert all(frac[ids.index(n)] == 0 for n in near)


def test_standing_still_the_anchor_itself_is_in_view_at_every_heading() -> None:
    camera = make_camera("equidistant", "offset-tilted")
    P = grid_positions(3, 3, 1.0)
    px, ok = predict_pixels(camera, T_world_body_from_pose(1.2, 0.9, 2.0), P[4:5])
    assert ok[0]
    frac = view_fractions(
        camera, P[4], (float(px[0, 0]), float(px[0, 1])), (np.zeros(2), 0.0), P,
        headings=72, inner_radius_px=INNER_PX,
    )  # fmt: skip
    assert frac[4] == 1.0


def _ident() -> Identifier:
    cfg = IdentificationConfig(probe="darken_one", frames_per_led=1)
    return Identifier(cfg, [1, 2, 3, 4, 5], motion_px=lambda a, b: 0.0)


def test_inconsistent_sightings_keep_the_newest_and_identification_goes_on() -> None:
    ident = _ident()
    ident.sightings = {2: Sighting(2, 100 * MS, (10.0, 20.0)), 4: Sighting(4, 900 * MS, (5.0, 6.0))}
    assert ident.done
    ident.keep_newest()
    assert ident.sightings == {4: Sighting(4, 900 * MS, (5.0, 6.0))}
    assert not ident.done
    assert ident.anchor == Sighting(4, 900 * MS, (5.0, 6.0))
    req = ident.next_request(1000 * MS)
    assert req is not None and req.dark and not (req.dark & {4})  # probes another, not all lit


def test_prefer_puts_the_ordered_candidates_next() -> None:
    ident = _ident()
    first = ident.next_request(0)
    assert first is not None and first.dark == frozenset({1})
    ident.prefer([5, 3])
    ident.led_confirmed(10 * MS, frozenset({2, 3, 4, 5}))
    ident.observe(20 * MS, frozenset({2, 3, 4, 5}), np.zeros((0, 2)), np.zeros(0))
    asked = [ident.next_request(t * MS) for t in (30, 31)]
    assert asked[0] is not None and asked[0].dark == frozenset({5})
