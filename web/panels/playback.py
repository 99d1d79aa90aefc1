"""History playback: where a robot went in a time window, from the kept poses (as
`GET /api/v1/history/poses?max_points=&floor=` and `/history/coverage` serve them), on the
floor shown (each floor's poses are in its own map frame).

The trail is coloured by the localizer's mode or by the pose's 1-sigma error; a time slider
moves a ghost robot along it; the heatmap counts every kept pose of the window (every robot)
per floor cell. Bounded whatever the window: the trail is at most `max_points` poses spread
evenly over it (thinned in the database), the heatmap one point a visited cell. Drawn in
this browser's scene only (`/playback/*`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from datetime import UTC, datetime, timedelta

import numpy as np
import numpy.typing as npt
import viser

from store.models import PoseRecord
from store.zones import PoseHistory
from web.colors import RGB, battery_color, mode_color
from web.panels.monitor import MODE_TEXT, local_time_text
from web.scene import wxyz_from_heading

WINDOWS: dict[str, float] = {
    "last 15 minutes": 0.25,
    "last hour": 1.0,
    "last 8 hours": 8.0,
    "last 24 hours": 24.0,
    "last 7 days": 168.0,
}
"""The time windows offered, hours."""
COLOR_BY = ("mode", "quality (1-sigma error)")
GHOST_COLOR: RGB = (60, 60, 200)
TRAIL_Z_M = 0.03
"""The played-back trail lies over the live trails (0.01 m) and thicker (0.12 m), metres."""
GOOD_SIGMA_M, BAD_SIGMA_M = 0.02, 0.10
"""The quality colours run from green (1-sigma at or under 2 cm) to red (10 cm and worse)."""


def quality_color(sigma_m: float | None) -> RGB:
    """Green at <= 2 cm 1-sigma error, red at >= 10 cm, grey when unknown."""
    if sigma_m is None or not math.isfinite(sigma_m):
        return battery_color(None)
    share = (BAD_SIGMA_M - sigma_m) / (BAD_SIGMA_M - GOOD_SIGMA_M)
    return battery_color(100.0 * min(1.0, max(0.0, share)))


def trail_segments(
    poses: Sequence[PoseRecord], by: str, *, max_gap_s: float
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.uint8]]:
    """Consecutive poses joined as segments (N, 2, 3) with their colours (N, 2, 3), each in
    the colour of its first pose; two poses further apart in time than `max_gap_s` are not
    joined (the robot had no pose meanwhile: joined, they would cut through walls)."""
    if len(poses) < 2:
        return np.zeros((0, 2, 3)), np.zeros((0, 2, 3), dtype=np.uint8)
    xy = np.array([[p.x, p.y] for p in poses], dtype=np.float64)
    t = np.array([p.t.timestamp() for p in poses])
    keep = np.diff(t) <= max_gap_s
    p3 = np.column_stack([xy, np.full(len(xy), TRAIL_Z_M)])
    seg = np.stack([p3[:-1], p3[1:]], axis=1)[keep]
    if by == "mode":
        rgb = [mode_color(p.mode) for p in poses[:-1]]
    else:
        rgb = [quality_color(p.sigma_m) for p in poses[:-1]]
    colors = np.repeat(np.array(rgb, dtype=np.uint8)[keep][:, None, :], 2, axis=1)
    return seg, colors


def heat_colors(counts: npt.NDArray[np.int64]) -> npt.NDArray[np.uint8]:
    """Counts (N,) as colours from pale yellow (1) to dark red (the most), on a log scale."""
    c = np.log1p(np.asarray(counts, dtype=np.float64))
    share = c / max(float(c.max()), 1e-9) if len(c) else c
    lo, hi = np.array([255, 235, 150]), np.array([170, 20, 20])
    rgb: npt.NDArray[np.uint8] = (lo + (hi - lo) * share[:, None]).round().astype(np.uint8)
    return rgb


def _ignore(_: object) -> None:
    """A GUI callback returns nothing (the actions return what they did, for tests)."""


class PlaybackPanel:
    """One browser's history folder and its `/playback` layer.

    Args:
        client: the browser.
        history: the kept poses.
        robots: the robots' names now (for the dropdown).
        notify: a pop-up for refusals.
        floor: the floor shown (its poses only; None: every floor's).
        max_points: the trail's bound, poses.
        cell_m: the heatmap's cell, metres.
        now: the wall clock (UTC; tests pass their own).
    """

    def __init__(
        self,
        client: viser.ClientHandle,
        history: PoseHistory,
        robots: Callable[[], Sequence[str]],
        notify: Callable[[str, str], None],
        floor: Callable[[], str | None] = lambda: None,
        *,
        max_points: int = 3000,
        cell_m: float = 0.5,
        now: Callable[[], datetime] = lambda: datetime.now(UTC),
    ) -> None:
        self.client, self.history, self.robots, self.notify = client, history, robots, notify
        self.floor = floor
        self.max_points, self.cell_m, self.now = max_points, cell_m, now
        self.poses: list[PoseRecord] = []
        gui = client.gui
        names = list(robots()) or ["-"]
        with gui.add_folder("History playback", expand_by_default=False):
            self.gui_robot = gui.add_dropdown("Robot", names)
            self.gui_window = gui.add_dropdown("Window", tuple(WINDOWS), initial_value="last hour")
            self.gui_by = gui.add_dropdown("Colour by", COLOR_BY)
            self.gui_heat = gui.add_checkbox("Heatmap of every robot", False)
            self.gui_load = gui.add_button("Show history")
            self.gui_time = gui.add_slider("Time", 0, 1, 1, 0, disabled=True)
            self.gui_at = gui.add_markdown("")
            self.gui_clear = gui.add_button("Clear")
            self.gui_text = gui.add_markdown("")
        self.gui_load.on_click(lambda _: _ignore(self.load()))
        self.gui_clear.on_click(lambda _: self.clear())
        self.gui_time.on_update(lambda _: _ignore(self.scrub(int(self.gui_time.value))))
        self.gui_by.on_update(lambda _: self._redraw_trail())

    def _window(self) -> tuple[datetime, datetime]:
        until = self.now()
        return until - timedelta(hours=WINDOWS[str(self.gui_window.value)]), until

    def load(self) -> str:
        """Read the window's poses of the chosen robot (and the heatmap) and draw them;
        returns the summary shown."""
        names = tuple(self.robots())
        if names and tuple(self.gui_robot.options) != names:
            self.gui_robot.options = names
        robot = str(self.gui_robot.value)
        since, until = self._window()
        floor = self.floor()
        self.poses, total = self.history.thinned(
            robot=robot, since=since, until=until, max_points=self.max_points, floor=floor
        )
        scene = self.client.scene
        scene.remove_by_name("/playback")
        scene.add_frame("/playback", show_axes=False)
        heat = self._draw_heatmap(since, until, floor) if self.gui_heat.value else ""
        where = "" if floor is None else f" on floor {floor}"
        if not self.poses:
            self.gui_time.disabled = True
            self.gui_at.content = ""
            text = f"no kept poses of **{robot}**{where} in the {self.gui_window.value}{heat}"
            self.gui_text.content = text
            return text
        self._redraw_trail()
        n = len(self.poses)
        self.gui_time.max = max(1, n - 1)
        self.gui_time.disabled = n < 2
        self.gui_time.value = n - 1  # type: ignore[misc]
        self.scrub(n - 1)
        every = "every pose" if n == total else f"every {math.ceil(total / n)}th of {total}"
        first, last = self.poses[0].t, self.poses[-1].t
        text = (
            f"**{robot}**{where}, {local_time_text(first)} to {local_time_text(last)}: {n} poses "
            f"({every}){heat}"
        )
        self.gui_text.content = text
        return text

    def _gap_s(self) -> float:
        """Poses further apart than this were not consecutive kept poses, seconds."""
        if len(self.poses) < 3:
            return 10.0
        dt = np.diff([p.t.timestamp() for p in self.poses])
        return max(10.0, 3.0 * float(np.median(dt)))

    def _redraw_trail(self) -> None:
        if not self.poses:
            return
        by = "mode" if self.gui_by.value == "mode" else "quality"
        seg, colors = trail_segments(self.poses, by, max_gap_s=self._gap_s())
        self.client.scene.add_line_segments(
            "/playback/trail", seg.astype(np.float32), colors, thickness=0.12
        )

    def scrub(self, index: int) -> PoseRecord | None:
        """Put the ghost robot at the `index`-th pose shown and say when it was there."""
        if not self.poses:
            return None
        p = self.poses[min(max(index, 0), len(self.poses) - 1)]
        self.client.scene.add_box(
            "/playback/ghost",
            color=GHOST_COLOR,
            dimensions=(0.45, 0.35, 0.25),
            position=(p.x, p.y, 0.125),
            wxyz=wxyz_from_heading(p.theta),
            opacity=0.6,
        )
        sigma = "" if p.sigma_m is None else f", 1-sigma {100 * p.sigma_m:.1f} cm"
        self.gui_at.content = (
            f"`{local_time_text(p.t)}` at ({p.x:.2f}, {p.y:.2f}) m, "
            f"{MODE_TEXT.get(p.mode, p.mode)}{sigma}"
        )
        return p

    def _draw_heatmap(self, since: datetime, until: datetime, floor: str | None) -> str:
        cells, n = self.history.cell_counts(self.cell_m, since=since, until=until, floor=floor)
        if not cells:
            return "; no poses for the heatmap"
        a = np.array(cells, dtype=np.int64)
        c = self.cell_m
        pts = np.column_stack([(a[:, 0] + 0.5) * c, (a[:, 1] + 0.5) * c, np.full(len(a), 0.005)])
        self.client.scene.add_point_cloud(
            "/playback/heatmap",
            pts.astype(np.float32),
            heat_colors(a[:, 2]),
            point_size=0.95 * c,
            point_shape="square",
            point_shading="flat",
        )
        return f"; heatmap: {n} poses of every robot in {len(a)} cells of {c:.2f} m"

    def clear(self) -> None:
        """Remove the trail, the ghost and the heatmap."""
        self.client.scene.remove_by_name("/playback")
        self.poses = []
        self.gui_time.disabled = True
        self.gui_text.content = self.gui_at.content = ""
