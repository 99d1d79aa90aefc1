"""Monitoring panels: robots, landmark batteries, events, a robot's uncertainty over time."""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable, Sequence
from datetime import UTC, datetime

import numpy as np
import viser

from web.battery_table import SORT_KEYS, battery_html
from web.roles import Session
from web.services import EventLine, LandmarkState, RobotState, ViewerSite

MODE_TEXT = {
    "landmark": "landmarks",
    "dead_reckoning": "dead reckoning",
    "identifying": "identifying",
    "lost": "LOST",
}


def position_sigma_m(robot: RobotState) -> float | None:
    """1-sigma position error sqrt(var x + var y) of a robot's estimate, metres."""
    if robot.pose is None:
        return None
    c = np.asarray(robot.pose.covariance)
    return math.sqrt(max(0.0, float(c[0, 0] + c[1, 1])))


def fix_age_s(robot: RobotState) -> float | None:
    """Seconds since the robot's last landmark fix."""
    if robot.last_fix_t_ns is None:
        return None
    return max(0.0, (robot.now_ns - robot.last_fix_t_ns) * 1e-9)


def local_time_text(t: datetime) -> str:
    """A UTC time (naive ones are UTC, as the database stores them) in this machine's local
    time with its zone: "2026-12-01 21:04:05 CET"."""
    aware = t if t.tzinfo is not None else t.replace(tzinfo=UTC)
    return aware.astimezone().strftime("%Y-%m-%d %H:%M:%S %Z")


def error_text(robot: RobotState) -> str:
    """The robots table's error column: the 1-sigma estimate while it tracks; "-" while it
    identifies or is lost (its covariance then means nothing: it reads 0.0 cm)."""
    sigma = position_sigma_m(robot)
    if sigma is None or robot.mode in ("identifying", "lost"):
        return "-"
    return f"{100 * sigma:.1f} cm"


def robots_table(robots: Sequence[RobotState]) -> str:
    """Markdown table: robot, mode, error estimate, quality, age of the last fix, and why
    it has no fix (the pose's reason, docs/quality.md)."""
    rows = [
        "| robot | mode | error (1 sigma) | quality | last fix | why no fix |",
        "|---|---|---|---|---|---|",
    ]
    for rb in robots:
        age = fix_age_s(rb)
        err = error_text(rb)
        fix = "never" if age is None else f"{age:.1f} s ago"
        quality = "-" if rb.quality is None else f"{rb.quality:.2f}"
        why = rb.reason_text.replace("|", "/") or "-"
        mode = MODE_TEXT.get(rb.mode, rb.mode)
        rows.append(f"| {rb.name} | {mode} | {err} | {quality} | {fix} | {why} |")
    return "\n".join(rows)


def events_text(events: Sequence[EventLine]) -> str:
    """Markdown list of events, newest first; a run of the same event (kind and message)
    is one line with its count and the time of the newest ("x5")."""
    if not events:
        return "_no events_"
    lines: list[str] = []
    runs: list[tuple[EventLine, int]] = []
    for e in events:
        if runs and (runs[-1][0].kind, runs[-1][0].message) == (e.kind, e.message):
            runs[-1] = (runs[-1][0], runs[-1][1] + 1)
        else:
            runs.append((e, 1))
    for e, n in runs:
        times = f" (x{n})" if n > 1 else ""
        kind = e.kind.replace("_", " ")
        # the kind in bold only when the message does not say it already ("robot lost:
        # robot r2 is lost" said it twice)
        said = set(kind.split()) <= set(e.message.lower().replace(":", " ").split())
        head = "" if said else f"**{kind}** "
        lines.append(f"- `{e.when}` {head}{e.message}{times}")
    return "\n".join(lines)


class UncertaintyHistory:
    """Per robot: (site time s, 1-sigma position error cm), bounded."""

    def __init__(self, maxlen: int = 600) -> None:
        self.maxlen = maxlen
        self._data: dict[str, deque[tuple[float, float]]] = {}

    def add(self, robots: Sequence[RobotState]) -> None:
        for rb in robots:
            sigma = position_sigma_m(rb)
            if sigma is not None:
                q = self._data.setdefault(rb.name, deque(maxlen=self.maxlen))
                q.append((rb.now_ns * 1e-9, 100.0 * sigma))

    def series(self, robot: str) -> tuple[np.ndarray, np.ndarray]:
        q = self._data.get(robot)
        if not q:
            return np.zeros(0), np.zeros(0)
        a = np.array(q)
        return a[:, 0] - a[-1, 0], a[:, 1]


class MonitorPanel:
    """Robots, batteries, events and the uncertainty plot in one browser's GUI."""

    def __init__(
        self,
        gui: viser.GuiApi,
        site: ViewerSite,
        session: Session,
        history: UncertaintyHistory,
        notify: Callable[[str, str], None],
    ) -> None:
        self.site, self.session, self.history, self.notify = site, session, history, notify
        names = [r.name for r in site.robots()] or ["-"]
        with gui.add_folder("Robots"):
            self.gui_robots = gui.add_markdown("")
            self.gui_robot = gui.add_dropdown("Robot", names)
            if session.can_operate:
                self.gui_relocalize = gui.add_button("Relocalize")
                self.gui_relocalize.on_click(lambda _: self._relocalize())
        with gui.add_folder("Uncertainty"):
            self.gui_plot = gui.add_uplot(
                # two placeholder points, not empty arrays: a uPlot created on empty data
                # never draws the series the later updates bring (viser 1.1's client)
                data=(np.array([-1.0, 0.0]), np.full(2, np.nan)),
                series=({"label": "time"}, {"label": "error", "stroke": "#2a7", "width": 2}),
                title=self._plot_title(),
                scales={"x": {"time": False}},
                axes=(
                    {"label": "seconds before now", "size": 36},
                    {"label": "error (cm)", "size": 52},
                ),
                legend={"show": False},  # one series: the axis titles say what it is
                padding=(14, 12, 0, 0),  # room for the top tick's label
                aspect=1.5,
            )
        with gui.add_folder("Events"):  # above the batteries: 39 rows pushed it off screen
            self.gui_events = gui.add_markdown("")
        with gui.add_folder("Landmark batteries", expand_by_default=False):
            self.gui_battery_sort = gui.add_dropdown("Sort", SORT_KEYS, initial_value=SORT_KEYS[0])
            self.gui_batteries = gui.add_html("")
        self._last: dict[str, str] = {}

    def _relocalize(self) -> None:
        name = self.gui_robot.value
        try:
            self.site.relocalize(name, actor=self.session.actor)
        except (KeyError, ValueError) as exc:
            self.notify("Relocalize failed", str(exc))
            return
        self.notify("Relocalize", f"{name} is identifying its landmarks again")

    def _set(
        self, key: str, handle: viser.GuiMarkdownHandle | viser.GuiHtmlHandle, text: str
    ) -> None:
        if self._last.get(key) != text:
            handle.content = text
            self._last[key] = text

    def refresh(
        self,
        robots: Sequence[RobotState],
        landmarks: Sequence[LandmarkState],
        events: Sequence[EventLine],
    ) -> None:
        """Update the tables and the plot (call at a few hertz)."""
        self._set("robots", self.gui_robots, robots_table(robots))
        self._set(
            "batteries", self.gui_batteries, battery_html(landmarks, self.gui_battery_sort.value)
        )
        self._set("events", self.gui_events, events_text(events))
        names = tuple(r.name for r in robots)
        if names and tuple(self.gui_robot.options) != names:
            self.gui_robot.options = names
        t, e = self.history.series(self.gui_robot.value)
        if len(t):
            title = self._plot_title()
            if self.gui_plot.title != title:
                self.gui_plot.title = title
            self.gui_plot.data = (t, e)

    def _plot_title(self) -> str:
        return f"{self.gui_robot.value}: 1-sigma position error"
