"""Click-to-inspect: a landmark or robot clicked in the 3D view is described in this panel.

A landmark: its position and map uncertainty, radio, battery (reading, charge, days left by
the trend and by the energy model at its duty), LED state and why, which robots use it now
and which one last did (since the viewer started), and who edited it last (the map's audit
log). A robot: its mode, position, error, last fix, the landmarks it uses and the zones it
is in. Operators and
admins also get "Cells replaced" for the landmark shown (after ticking the confirmation), as
`POST /api/v1/landmarks/{id}/cells-replaced?confirm=true`.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import viser
from matplotlib.path import Path as PolygonPath

from store.errors import NotFoundError, UnavailableError
from store.models import ZoneRecord
from web.panels.monitor import MODE_TEXT, error_text, fix_age_s, local_time_text
from web.roles import Session
from web.services import LandmarkState, RobotState, ViewerSite
from web.zones_view import on_floor


@dataclass(frozen=True)
class Use:
    """The last time a robot used a landmark for a fix: robot name, wall clock seconds."""

    robot: str
    wall_s: float


def _ignore(_: object) -> None:
    """A GUI callback returns nothing (the actions return what they did, for tests)."""


class LastUse:
    """Which robot last used each landmark, and when (fed by the viewer's update loop;
    thread-safe)."""

    def __init__(self, clock: Callable[[], float] = time.time) -> None:
        self.clock = clock
        self._last: dict[int, Use] = {}
        self._lock = threading.Lock()

    def add(self, robots: Sequence[RobotState]) -> None:
        now = self.clock()
        with self._lock:
            for rb in robots:
                if rb.pose is not None and rb.mode == "landmark":
                    for lid in rb.pose.landmark_ids:
                        self._last[int(lid)] = Use(rb.name, now)

    def of(self, landmark_id: int) -> Use | None:
        with self._lock:
            return self._last.get(landmark_id)


def _ago(seconds: float) -> str:
    if seconds < 90:
        return f"{seconds:.0f} s ago"
    if seconds < 5400:
        return f"{seconds / 60:.0f} min ago"
    return f"{seconds / 3600:.1f} h ago"


def landmark_text(
    lm: LandmarkState,
    robots: Sequence[RobotState],
    last: Use | None,
    edits: Sequence[tuple[str, str, str]],
    now_s: float,
) -> str:
    """Markdown describing a landmark; `edits`: (local time, actor, action), newest first."""
    sigma = "" if lm.sigma_m is None else f" \u00b1{1000 * lm.sigma_m:.1f} mm"
    lines = [
        f"**Landmark {lm.id}**" + (" (surveyed, locked)" if lm.locked else ""),
        f"- at ({lm.x:.3f}, {lm.y:.3f}, {lm.z:.3f}) m{sigma}",
        f"- radio {lm.radio or 'none'}"
        + ("" if lm.reachable else " **not answering**")
        + (" - **doubted**: robots expected it but rarely used it" if lm.doubted else ""),
    ]
    if lm.supply_mv is None:
        lines.append("- battery: not read yet")
    else:
        trend = "no trend yet" if lm.days_left is None else f"{lm.days_left:.0f} d by the trend"
        model = "" if lm.model_days is None else f", {lm.model_days:.0f} d at its duty"
        pct = "" if lm.percent is None else f" ({lm.percent:.0f} %)"
        lines.append(
            f"- battery {lm.supply_mv / 1000:.2f} V{pct}: {trend}{model}"
            + (" **LOW**" if lm.low else "")
        )
    duty = "" if lm.duty is None else f", lit {100 * lm.duty:.0f} % of the time"
    why = f" ({lm.lit_reason})" if lm.lit and lm.lit_reason else ""
    lines.append(f"- LED {'on' if lm.lit else 'off'}{why}{duty}")
    users = [r.name for r in robots if r.pose is not None and lm.id in r.pose.landmark_ids]
    lines.append(f"- used now by {', '.join(users)}" if users else "- used by no robot now")
    if last is not None:
        lines.append(f"- last used by {last.robot}, {_ago(max(0.0, now_s - last.wall_s))}")
    for when, actor, action in edits[:3]:
        lines.append(f"- {action} by `{actor}`, {when}")
    if not edits:
        lines.append("- no edits in the audit log")
    return "\n".join(lines)


def zones_at(zones: Sequence[ZoneRecord], x: float, y: float) -> list[str]:
    """Names of the zones whose polygon holds (x, y)."""
    return [z.name for z in zones if PolygonPath(np.asarray(z.polygon)).contains_point((x, y))]


def robot_text(rb: RobotState, zones: Sequence[ZoneRecord] = ()) -> str:
    """Markdown describing a robot (`zones`: those of the floor shown)."""
    lines = [f"**Robot {rb.name}**: {MODE_TEXT.get(rb.mode, rb.mode)}"]
    if rb.pose is not None:
        p = rb.pose
        lines.append(f"- at ({p.x:.2f}, {p.y:.2f}) m, heading {p.theta * 57.29578:.1f} deg")
        lines.append(f"- error (1 sigma) {error_text(rb)}")
        ids = ", ".join(str(i) for i in p.landmark_ids) or "none"
        lines.append(f"- landmarks used: {ids}")
        inside = zones_at(zones, p.x, p.y)
        if inside:
            lines.append(f"- in zone {', '.join(inside)}")
    age = fix_age_s(rb)
    lines.append("- last landmark fix: " + ("never" if age is None else _ago(age)))
    return "\n".join(lines)


class InspectPanel:
    """One browser's "Selected" folder."""

    def __init__(
        self,
        gui: viser.GuiApi,
        site: ViewerSite,
        session: Session,
        last_use: LastUse,
        notify: Callable[[str, str], None],
    ) -> None:
        self.site, self.session, self.last_use, self.notify = site, session, last_use, notify
        self.selected: tuple[str, str] | None = None
        """("landmark", "17") or ("robot", "r1") shown, None before a click."""
        with gui.add_folder("Selected"):
            self.gui_text = gui.add_markdown("_click a landmark or a robot in the view_")
            self.gui_sure = self.gui_cells = None
            if session.can_operate:
                self.gui_sure = gui.add_checkbox("Yes, its cells are new", False, visible=False)
                self.gui_cells = gui.add_button("Cells replaced", visible=False)
                self.gui_cells.on_click(lambda _: _ignore(self.cells_replaced()))

    def select(self, kind: str, key: str) -> str:
        """Show a landmark ("landmark", its ID) or a robot ("robot", its name)."""
        self.selected = (kind, key)
        if self.gui_sure is not None and self.gui_cells is not None:
            self.gui_sure.value = False  # type: ignore[misc]
            self.gui_sure.visible = self.gui_cells.visible = kind == "landmark"
        return self.refresh()

    def refresh(self) -> str:
        """Redraw what is selected (call at a few hertz)."""
        if self.selected is None:
            return str(self.gui_text.content)
        kind, key = self.selected
        robots = self.site.robots()
        if kind == "robot":
            rb = next((r for r in robots if r.name == key), None)
            store = self.site.zones()
            zones = [] if store is None else on_floor(store.list(), self.site.floor_shown())
            text = f"robot {key} is not shown" if rb is None else robot_text(rb, zones)
        else:
            lid = int(key)
            lm = next((m for m in self.site.landmarks() if m.id == lid), None)
            if lm is None:
                text = f"landmark {lid} is not in the map shown"
            else:
                text = landmark_text(
                    lm, robots, self.last_use.of(lid), self._edits(lid), time.time()
                )
        if self.gui_text.content != text:
            self.gui_text.content = text
        return text

    def _edits(self, landmark_id: int) -> list[tuple[str, str, str]]:
        repo = self.site.map_history()
        if repo is None:
            return []
        return [
            (local_time_text(r.t), r.actor, r.action)
            for r in repo.audit(3, landmark_id=landmark_id)
        ]

    def cells_replaced(self) -> bool:
        """ "Cells replaced" for the landmark shown, once the confirmation is ticked."""
        if self.selected is None or self.selected[0] != "landmark" or self.gui_sure is None:
            return False
        lid = int(self.selected[1])
        if not self.gui_sure.value:
            self.notify("Cells replaced", f"tick 'Yes, its cells are new' for landmark {lid}")
            return False
        try:
            done = self.site.replace_cells(lid, actor=self.session.actor)
        except (KeyError, ValueError, NotFoundError, UnavailableError, TimeoutError) as exc:
            self.notify("Cells replaced", f"landmark {lid}: {exc}")
            return False
        self.gui_sure.value = False  # type: ignore[misc]
        read = (
            f"reads {done.battery.supply_mv / 1000:.2f} V"
            if done.read and done.battery.supply_mv is not None
            else f"not read yet ({done.why_not})"
        )
        self.notify("Cells replaced", f"landmark {lid}: battery estimate starts over; {read}")
        self.refresh()
        return True
