"""Zones: the list of the site's zones for everyone, and for admins (as the API's
`POST/PATCH/DELETE /api/v1/zones` require) making, editing and deleting them.

A new zone's corners are typed ("x, y; x, y; ...", metres) or clicked on the floor with
"Draw on the floor" ticked (each click adds the point where the ray meets the floor; the
draft shows in this browser only). The panel calls `store.zones.ZoneStore`, as the API does;
the shared `/zones` layer (`web.zones_view`) redraws on the store's change.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
import viser

from store.errors import ConflictError, NotFoundError
from store.models import ZoneRecord
from store.zones import ZoneStore, check_polygon
from web.roles import Session
from web.status_line import StatusLine
from web.zones_view import DRAFT_COLOR, on_floor, ring_segments

NEW = "(new zone)"


def parse_points(text: str) -> list[tuple[float, float]]:
    """ "x, y; x, y; ..." (metres) as points; ValueError naming the item that is not "x, y"."""
    points = []
    for i, item in enumerate(p for p in text.replace("\n", ";").split(";") if p.strip()):
        parts = item.replace(",", " ").split()
        try:
            if len(parts) != 2:
                raise ValueError
            points.append((float(parts[0]), float(parts[1])))
        except ValueError:
            raise ValueError(f"point {i + 1}: {item.strip()!r} is not 'x, y' in metres") from None
    return points


def points_text(points: Sequence[Sequence[float]]) -> str:
    """Points as the panel's text: "1.00, 2.00; 3.50, 2.00"."""
    return "; ".join(f"{p[0]:.2f}, {p[1]:.2f}" for p in points)


def floor_point(
    origin: Sequence[float], direction: Sequence[float], z: float = 0.0
) -> tuple[float, float] | None:
    """Where a click's ray meets the plane at height `z` (None: it points away from it)."""
    o, d = np.asarray(origin, dtype=np.float64), np.asarray(direction, dtype=np.float64)
    if abs(d[2]) < 1e-9:
        return None
    t = (z - o[2]) / d[2]
    if t <= 0:
        return None
    p = o + t * d
    return float(p[0]), float(p[1])


def zones_text(zones: Sequence[ZoneRecord]) -> str:
    """Markdown list: name, floor, corners and dwell limit of each zone."""
    if not zones:
        return "_no zones_ (`POST /api/v1/zones`)"
    lines = []
    for z in zones:
        floor = f", floor {z.floor}" if z.floor else ""
        dwell = f", dwell {z.dwell_s:.0f} s" if z.dwell_s is not None else ""
        lines.append(f"- **{z.name}** ({len(z.polygon)} corners{floor}{dwell})")
    return "\n".join(lines)


def _ignore(_: object) -> None:
    """A GUI callback returns nothing (the actions return what they did, for tests)."""


class ZonesPanel:
    """One browser's zones folder.

    Args:
        client: the browser (its GUI, and its scene for the draft).
        store: the site's zones.
        session: who is signed in (admins edit).
        floor: the floor shown now (new zones go on it; None: every floor, zones of no floor).
        notify: a pop-up for refusals.
    """

    def __init__(
        self,
        client: viser.ClientHandle,
        store: ZoneStore,
        session: Session,
        floor: Callable[[], str | None],
        notify: Callable[[str, str], None],
    ) -> None:
        self.client, self.store, self.session = client, store, session
        self.floor, self.notify = floor, notify
        gui = client.gui
        self._listed = ""
        self._options: tuple[str, ...] = ()
        self._clicking = False
        with gui.add_folder("Zones", expand_by_default=False):
            self.gui_list = gui.add_markdown("")
            self.editing = session.can_commission
            if self.editing:
                self.gui_zone = gui.add_dropdown("Zone", (NEW,))
                self.gui_name = gui.add_text("Name", "")
                self.gui_dwell = gui.add_number(
                    "Dwell event after (s, 0: none)", 0.0, min=0.0, max=86_400.0, step=1.0
                )
                self.gui_points = gui.add_text("Corners (x, y; ... m)", "")
                self.gui_draw = gui.add_checkbox("Draw on the floor (click corners)", False)
                self.gui_create = gui.add_button("Create zone")
                self.gui_save = gui.add_button("Save changes")
                self.gui_sure = gui.add_checkbox("Yes, delete this zone", False)
                self.gui_delete = gui.add_button("Delete zone")
                self.gui_status = gui.add_markdown("")
                self.status = StatusLine(self.gui_status)
                self.gui_zone.on_update(lambda _: self._load())
                self.gui_draw.on_update(lambda _: self._drawing(bool(self.gui_draw.value)))
                self.gui_points.on_update(lambda _: self._draw_draft())
                self.gui_create.on_click(lambda _: _ignore(self.create()))
                self.gui_save.on_click(lambda _: _ignore(self.save()))
                self.gui_delete.on_click(lambda _: _ignore(self.delete()))
        self.refresh()

    # -- reading -------------------------------------------------------------------------
    def refresh(self) -> None:
        """The list and the zone dropdown (call at a few hertz)."""
        zones = on_floor(self.store.list(), self.floor())
        text = zones_text(zones)
        if text != self._listed:
            self.gui_list.content = self._listed = text
        if self.editing:
            self.status.refresh()
            options = (NEW, *(f"{z.id}: {z.name}" for z in zones))
            if options != self._options:
                self._options = options
                self.gui_zone.options = options

    def _selected(self) -> int | None:
        value = str(self.gui_zone.value)
        return None if value == NEW else int(value.split(":", 1)[0])

    def _load(self) -> None:
        zid = self._selected()
        if zid is None:
            return
        try:
            z = self.store.get(zid)
        except NotFoundError as exc:
            self._refused(str(exc))
            return
        self.gui_name.value = z.name  # type: ignore[misc]
        self.gui_dwell.value = 0.0 if z.dwell_s is None else z.dwell_s  # type: ignore[misc]
        self.gui_points.value = points_text(z.polygon)  # type: ignore[misc]

    # -- drawing on the floor ---------------------------------------------------------------
    def _drawing(self, on: bool) -> None:
        """Listen to this browser's clicks on the scene while drawing (only then: a scene
        click handler takes the clicks that would otherwise go to the camera controls)."""
        scene = self.client.scene
        if on and not self._clicking:
            scene.on_click()(self._on_floor_click)
            self._draw_draft()
        elif not on and self._clicking:
            scene.remove_click_callback(self._on_floor_click)
            scene.remove_by_name("/zones_draft")
        self._clicking = on

    def _on_floor_click(self, event: viser.SceneClickEvent) -> None:
        self.add_corner(event.ray_origin, event.ray_direction)

    def add_corner(self, origin: Sequence[float], direction: Sequence[float]) -> None:
        """Add the floor point a click's ray meets to the corners."""
        p = floor_point(origin, direction)
        if p is None:
            return
        text = str(self.gui_points.value).strip()
        self.gui_points.value = (text + "; " if text else "") + points_text([p])  # type: ignore[misc]
        self._draw_draft()

    def _draw_draft(self) -> None:
        if not self.editing:
            return
        try:
            points = parse_points(str(self.gui_points.value))
        except ValueError:
            return
        self.client.scene.add_line_segments(
            "/zones_draft", ring_segments(points, z=0.03), DRAFT_COLOR, thickness=0.05
        )

    # -- actions (admin) ---------------------------------------------------------------------
    def _fields(self) -> tuple[str, list[tuple[float, float]], float | None]:
        name = str(self.gui_name.value).strip()
        if not name:
            raise ValueError("zone: give it a name")
        points = parse_points(str(self.gui_points.value))
        check_polygon(points, source="zone corners")
        dwell = float(self.gui_dwell.value)
        return name, points, dwell if dwell > 0 else None

    def create(self) -> ZoneRecord | None:
        """Store a new zone from the fields, on the floor shown."""
        try:
            name, points, dwell = self._fields()
            z = self.store.create(name, points, floor=self.floor() or "", dwell_s=dwell)
        except (ValueError, ConflictError) as exc:
            self._refused(str(exc))
            return None
        self._done(f"zone **{z.name}** created ({len(z.polygon)} corners)")
        return z

    def save(self) -> ZoneRecord | None:
        """Store the fields into the zone chosen."""
        zid = self._selected()
        try:
            if zid is None:
                raise ValueError("choose the zone to change (or Create a new one)")
            name, points, dwell = self._fields()
            z = self.store.update(
                zid, name=name, polygon=points, dwell_s=dwell, clear_dwell=dwell is None
            )
        except (ValueError, ConflictError, NotFoundError) as exc:
            self._refused(str(exc))
            return None
        self._done(f"zone **{z.name}** saved")
        return z

    def delete(self) -> bool:
        """Delete the zone chosen, once "Yes, delete this zone" is ticked."""
        zid = self._selected()
        if zid is None:
            self._refused("choose the zone to delete")
            return False
        if not self.gui_sure.value:
            self._refused("tick 'Yes, delete this zone' first")
            return False
        try:
            self.store.delete(zid)
        except NotFoundError as exc:
            self._refused(str(exc))
            return False
        self.gui_sure.value = False  # type: ignore[misc]
        self.gui_zone.value = NEW  # type: ignore[misc]
        self._done(f"zone {zid} deleted")
        return True

    def _done(self, text: str) -> None:
        self.status.say(text)
        self.gui_draw.value = False  # type: ignore[misc]
        self._drawing(False)
        self.refresh()

    def _refused(self, text: str) -> None:
        self.status.say(f"**refused**: {text}")
        self.notify("Zones", text)
