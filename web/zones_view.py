"""The site's zones on the floor (`/zones/<id>`: outline and name, shared by every browser).

Zones come from `store.zones.ZoneStore`, as `/api/v1/zones` serves them; the layer redraws
when the store tells of a change (a zone made, edited or deleted through the API or any
browser shows within a landmark refresh, 0.5 s) or the floor shown changes. Only the zones of
the floor shown are drawn (and those of no floor, `""`, on every floor). A zone watched for
dwelling (it has a `dwell_s`) is drawn amber, the others teal.
"""

from __future__ import annotations

import threading
from collections.abc import Sequence

import numpy as np
import numpy.typing as npt
import viser

from store.models import ZoneRecord
from store.zones import ZoneStore
from web.colors import RGB

ZONE_COLOR: RGB = (0, 140, 150)
"""Teal: a zone with enter and exit events."""
DWELL_ZONE_COLOR: RGB = (230, 140, 0)
"""Amber: a zone that also raises `zone_dwell` after `dwell_s`."""
DRAFT_COLOR: RGB = (200, 40, 160)
"""A zone being drawn in one browser, not stored yet."""
ZONE_Z_M = 0.02
"""Outlines lie just above the floor and the floor plan, metres."""


def zone_color(zone: ZoneRecord) -> RGB:
    """Amber for a zone watched for dwelling, teal for the others."""
    return DWELL_ZONE_COLOR if zone.dwell_s is not None else ZONE_COLOR


def ring_segments(
    polygon: Sequence[Sequence[float]], z: float = ZONE_Z_M
) -> npt.NDArray[np.float64]:
    """A closed polygon's edges as line segments, shape (N, 2, 3) (an open one of fewer than
    3 points: its N - 1 edges)."""
    p = np.asarray(polygon, dtype=np.float64).reshape(-1, 2)
    if len(p) < 2:
        return np.zeros((0, 2, 3))
    closed = len(p) >= 3
    a = p if closed else p[:-1]
    b = np.roll(p, -1, axis=0) if closed else p[1:]
    zs = np.full((len(a), 1), z)
    return np.stack([np.hstack([a, zs]), np.hstack([b, zs])], axis=1)


def zone_label(zone: ZoneRecord) -> str:
    """The name shown inside a zone, with its dwell limit: "dock (dwell 30 s)"."""
    if zone.dwell_s is None:
        return zone.name
    return f"{zone.name} (dwell {zone.dwell_s:.0f} s)"


def on_floor(zones: Sequence[ZoneRecord], floor: str | None) -> list[ZoneRecord]:
    """The zones shown with `floor` shown (None: every floor): its own and the site-wide."""
    return [z for z in zones if floor is None or z.floor in ("", floor)]


class ZonesLayer:
    """The `/zones` nodes of the shared scene."""

    def __init__(self, scene: viser.SceneApi, store: ZoneStore) -> None:
        self.scene, self.store = scene, store
        self._dirty = threading.Event()
        self._dirty.set()
        self._floor: str | None = None
        self.shown: dict[int, tuple[ZoneRecord, RGB]] = {}
        """What is drawn, by zone id (for tests)."""
        store.add_listener(lambda _zones: self._dirty.set())

    def refresh(self, floor: str | None) -> bool:
        """Redraw when the zones or the floor shown changed; True when it did."""
        if not self._dirty.is_set() and floor == self._floor:
            return False
        self._dirty.clear()
        self._floor = floor
        zones = on_floor(self.store.list(), floor)
        self.scene.remove_by_name("/zones")
        self.scene.add_frame("/zones", show_axes=False)
        self.shown = {}
        for z in zones:
            assert z.id is not None  # stored
            color = zone_color(z)
            self.scene.add_line_segments(
                f"/zones/{z.id}/outline", ring_segments(z.polygon), color, thickness=0.06
            )
            c = np.asarray(z.polygon, dtype=np.float64).mean(axis=0)
            self.scene.add_label(
                f"/zones/{z.id}/label",
                zone_label(z),
                position=(c[0], c[1], ZONE_Z_M),
                anchor="center-center",
                font_screen_scale=0.9,
            )
            self.shown[z.id] = (z, color)
        return True
