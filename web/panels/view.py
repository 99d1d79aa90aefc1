"""This browser's camera (top view, oblique view, follow a robot) and the legend of every
colour the scene uses."""

from __future__ import annotations

import logging
from collections.abc import Sequence

import numpy as np
import viser

from web.camera_views import TopView, apply_oblique_view, apply_top_view, follow
from web.colors import (
    DOUBTED_COLOR,
    LIT_COLOR,
    MODE_COLORS,
    RGB,
    ROUTE_COLOR,
    SURVEY_STATE_COLORS,
    SURVEY_STATE_NAMES,
    UNKNOWN_COLOR,
    UNREACHABLE_COLOR,
    battery_color,
    robot_color,
)
from web.footprint import Bounds
from web.services import RobotState

log = logging.getLogger(__name__)
NOBODY = "nobody"
MODE_NAMES = {
    "landmark": "landmark fix",
    "dead_reckoning": "dead reckoning (odometry only)",
    "identifying": "identifying its landmarks",
    "lost": "lost",
}
COVERAGE_COUNT: tuple[tuple[RGB, str], ...] = (
    ((210, 40, 40), "no landmark in view"),
    ((230, 160, 20), "1 landmark (no fix from it alone)"),
    ((40, 160, 60), "2 or more"),
)


def swatch(rgb: RGB, text: str, *, round_: bool = False) -> str:
    """One legend row: a colour square (or dot) and its meaning, as HTML."""
    radius = "50%" if round_ else "2px"
    return (
        f'<div style="display:flex;align-items:center;gap:6px;margin:2px 0">'
        f'<span style="flex:none;width:12px;height:12px;border-radius:{radius};'
        f'background:rgb{rgb};border:1px solid #0003"></span>'
        f"<span>{text}</span></div>"
    )


def gradient(stops: Sequence[RGB], left: str, right: str) -> str:
    """A colour ramp with its two ends named, as HTML."""
    css = ", ".join(f"rgb{c}" for c in stops)
    return (
        f'<div style="margin:2px 0"><div style="height:10px;border-radius:2px;'
        f'background:linear-gradient(to right, {css})"></div>'
        f'<div style="display:flex;justify-content:space-between;font-size:0.85em">'
        f"<span>{left}</span><span>{right}</span></div></div>"
    )


def legend_html(robots: Sequence[str] = ()) -> str:
    """Every colour of the scene: robots by mode, their trails, landmarks by battery and
    state, lines (`robots`: the names in the order the scene met them, for their colours)."""
    head = '<div style="font-weight:600;margin-top:6px">{}</div>'
    rows = [head.format("Robots (box colour = localizer mode)")]
    rows += [swatch(MODE_COLORS[m], MODE_NAMES[m]) for m in MODE_NAMES]
    rows += [
        swatch((80, 160, 200), "blue outline: ceiling its camera can use"),
        swatch((250, 220, 90), "yellow lines: landmarks used in the last fix"),
        swatch((150, 150, 150), "ring: 3-sigma position uncertainty"),
    ]
    rows += [swatch(robot_color(i), f"trail of {name}") for i, name in enumerate(robots)]
    rows.append(head.format("Landmarks (sphere colour = battery)"))
    rows.append(gradient([battery_color(p) for p in (0, 25, 50, 75, 100)], "0 %", "100 %"))
    rows += [
        swatch(UNKNOWN_COLOR, "battery never read", round_=True),
        swatch(UNREACHABLE_COLOR, "radio does not answer", round_=True),
        swatch(DOUBTED_COLOR, "doubted: robots expected it but did not see it", round_=True),
        swatch(LIT_COLOR, "halo: LED lit", round_=True),
    ]
    rows.append(head.format("Coverage (floor)"))
    rows += [swatch(c, t) for c, t in COVERAGE_COUNT]
    rows.append(gradient([battery_color(p) for p in (0, 50, 100)], ">= 5 cm / no fix", "<= 1 cm"))
    rows.append(head.format("Survey (ceiling: 1-sigma ellipses, magnified)"))
    rows += [swatch(SURVEY_STATE_COLORS[k], t) for k, t in SURVEY_STATE_NAMES.items()]
    rows.append(swatch(ROUTE_COLOR, "suggested route (floor)"))
    return '<div style="font-size:0.9em">' + "".join(rows) + "</div>"


class ViewPanel:
    """Top view, oblique view and follow-a-robot for one browser, and the legend."""

    def __init__(
        self,
        client: viser.ClientHandle,
        bounds: Bounds,
        ceiling_z: float,
        robot_names: Sequence[str],
        *,
        follow_hz: float = 10.0,
    ) -> None:
        self.client, self.bounds, self.ceiling_z = client, bounds, ceiling_z
        self.top: TopView | None = None  # fitted to the window once its size is known
        self.follow_period_s = 1.0 / follow_hz
        self._next_follow = 0.0
        gui = client.gui
        with gui.add_folder("View"):
            self.gui_camera = gui.add_button_group("Camera", ("Top view", "Oblique view"))
            self.gui_follow = gui.add_dropdown("Follow robot", (NOBODY, *robot_names))
        with gui.add_folder("Legend", expand_by_default=False):
            self.gui_legend = gui.add_html(legend_html(robot_names))
        self.gui_camera.on_click(lambda e: self.set_view(str(e.target.value)))

    def set_view(self, which: str) -> None:
        """ "Top view" or "Oblique view" for this browser (keeps following a robot)."""
        cam = self.client.camera
        if which.startswith("Top"):
            apply_top_view(cam, self.bounds, self.top)
        else:
            apply_oblique_view(cam, self.bounds, self.ceiling_z)

    def fit_window(self, width_px: int, height_px: int, panel_px: float) -> None:
        """Fit the top view to this browser's window (`panel_px` of it covered by the panel
        at the right: none on a phone, whose panel folds to a bar below) and show it."""
        if width_px <= 0 or height_px <= 0:
            return
        self.top = TopView(
            screen_aspect=width_px / height_px, panel_share=min(0.6, panel_px / width_px)
        )
        apply_top_view(self.client.camera, self.bounds, self.top)

    def set_robots(self, names: Sequence[str]) -> None:
        """The robots to follow and in the legend (one that joined since: an agent, say)."""
        options = (NOBODY, *names)
        if tuple(self.gui_follow.options) != options:
            self.gui_follow.options = options
            self.gui_legend.content = legend_html(names)

    def follow(self, robots: Sequence[RobotState], now_s: float) -> None:
        """Keep the followed robot under the camera's look-at point (at `follow_hz`)."""
        name = self.gui_follow.value
        if name == NOBODY or now_s < self._next_follow:
            return
        self._next_follow = now_s + self.follow_period_s
        rb = next((r for r in robots if r.name == name), None)
        if rb is None or rb.pose is None:
            return
        cam = self.client.camera
        try:  # from where the camera looks now (the user may have panned or zoomed)
            follow(cam, np.asarray(cam.look_at, dtype=np.float64), (rb.pose.x, rb.pose.y))
        except AssertionError:  # viser: the browser has not reported its camera yet
            log.debug("viewer: no camera state yet for client %s", self.client.client_id)
