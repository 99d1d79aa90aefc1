"""The survey panel: a thin client of the server's live survey (the same one
`/api/v1/commissioning/survey` drives). Pick a robot, start, watch every landmark's estimate
converge on the ceiling with its 1-sigma ellipse (coloured by state) and the suggested route
on the floor, then stop and solve, and accept the result as a whole or landmark by landmark
(through the map's data layer, audited and undoable). Admin only.

The scene layer is this browser's (`client.scene`), under `/survey`.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np
import viser

from live.survey.service import Proposal, SurveyStatus
from localizer.types import FloatArray
from web.colors import RGB, ROUTE_COLOR, SURVEY_STATE_COLORS
from web.roles import Session
from web.segments import polyline_segments
from web.services import LandmarkState, ViewerSite

MIN_RING_M = 0.15
"""An ellipse is drawn at least this large (a converged one is millimetres across)."""
UNSEEN_RING_M = 0.2
ROUTE_Z_M = 0.03


def ellipse_ring(
    center: Sequence[float], axes: tuple[float, float, float], scale: float, n: int = 24
) -> FloatArray:
    """The closed outline (n + 1, 2) of an ellipse (major m, minor m, angle rad) drawn
    `scale` times its size, at least `MIN_RING_M` across each axis."""
    a = max(axes[0] * scale, MIN_RING_M)
    b = max(axes[1] * scale, MIN_RING_M)
    t = np.linspace(0.0, 2.0 * math.pi, n + 1)
    c, s = math.cos(axes[2]), math.sin(axes[2])
    x, y = a * np.cos(t), b * np.sin(t)
    return np.column_stack([center[0] + c * x - s * y, center[1] + s * x + c * y])


def survey_segments(
    status: SurveyStatus, landmarks: Sequence[LandmarkState], scale: float
) -> dict[str, FloatArray]:
    """Line segments (N, 2, 3) by state: each estimate's ellipse at its height, and a ring
    at the map position of each landmark not placed yet ("unseen")."""
    out: dict[str, list[FloatArray]] = {k: [] for k in SURVEY_STATE_COLORS}
    placed = {p.landmark_id for p in status.proposals}
    for p in status.proposals:
        ring = ellipse_ring((p.x, p.y), p.ellipse, scale)
        out[p.state].append(polyline_segments(np.column_stack([ring, np.full(len(ring), p.z)])))
    if status.state == "driving" or status.proposals:
        for lm in landmarks:
            if lm.id not in placed:
                ring = ellipse_ring((lm.x, lm.y), (UNSEEN_RING_M, UNSEEN_RING_M, 0.0), 1.0, 12)
                z = np.full(len(ring), lm.z)
                out["unseen"].append(polyline_segments(np.column_stack([ring, z])))
    return {k: np.concatenate(v) if v else np.zeros((0, 2, 3)) for k, v in out.items()}


def progress_text(status: SurveyStatus, n_map: int) -> str:
    """The progress line: identified / converged of the map, robot time, blinks."""
    if status.state == "idle":
        return "Lock two or more surveyed landmarks far apart (the anchors), pick a robot, start."
    counts = {s: sum(p.state == s for p in status.proposals) for s in SURVEY_STATE_COLORS}
    placed = len(status.proposals)
    head = f"**{status.state}** with {status.robot}"
    if status.state in ("driving", "done"):
        head += (
            f": {placed} of {n_map} landmarks placed, {counts['converged']} converged "
            f"(1-sigma <= {1000 * status.converged_sigma_m:.0f} mm), {counts['flagged']} flagged; "
            f"robot time {status.drive_s:.0f} s; {status.blinks} blinks"
        )
    lines = [head]
    if status.message:
        lines.append(status.message)
    if status.accepted:
        lines.append(f"accepted: {', '.join(map(str, status.accepted))}")
    return "\n\n".join(lines)


def proposals_table(proposals: Sequence[Proposal], limit: int = 60) -> str:
    """Markdown table of the estimate, least certain first."""
    if not proposals:
        return ""
    rows = sorted(proposals, key=lambda p: (p.state == "anchor", -p.sigma_m))
    lines = ["| ID | state | 1σ mm | moved cm | views |", "|---|---|---|---|---|"]
    for p in rows[:limit]:
        flag = f" ({'; '.join(p.flags)})" if p.flags else ""
        lines.append(
            f"| {p.landmark_id} | {p.state}{flag} | {1000 * p.sigma_m:.1f} | "
            f"{100 * p.moved_m:.1f} | {p.views} |"
        )
    return "\n".join(lines)


class SurveyPanel:
    """One admin browser's view of the (site-wide) live survey."""

    def __init__(
        self,
        client: viser.ClientHandle,
        site: ViewerSite,
        session: Session,
        notify: Callable[[str, str], None],
    ) -> None:
        self.client, self.site, self.session, self.notify = client, site, session, notify
        gui = client.gui
        names = [r.name for r in site.robots()] or ["-"]
        with gui.add_folder("Survey by driving"):
            self.gui_robot = gui.add_dropdown("Surveying robot", names)
            self.gui_start = gui.add_button("Start survey")
            self.gui_stop = gui.add_button("Stop and solve", disabled=True)
            self.gui_cancel = gui.add_button("Cancel survey", color="red", disabled=True)
            self.gui_progress = gui.add_markdown(progress_text(site.survey_status(), 0))
            self.gui_scale = gui.add_number(
                "Ellipses drawn (x)", 20.0, min=1.0, max=500.0, step=1.0
            )
            self.gui_route = gui.add_checkbox("Show suggested route", True)
            self.gui_id = gui.add_number("Survey landmark ID", 0, min=0, step=1)
            self.gui_accept_one = gui.add_button("Accept this landmark", disabled=True)
            self.gui_accept_all = gui.add_button("Accept all unflagged", disabled=True)
            self.gui_table = gui.add_markdown("")
        self.gui_start.on_click(lambda _: self._run(self._start))
        self.gui_stop.on_click(lambda _: self._run(lambda: self.site.survey_stop(actor=self.actor)))
        self.gui_cancel.on_click(
            lambda _: self._run(lambda: self.site.survey_cancel(actor=self.actor))
        )
        self.gui_accept_one.on_click(lambda _: self._run(self._accept_one))
        self.gui_accept_all.on_click(
            lambda _: self._run(lambda: self.site.survey_accept(None, actor=self.actor))
        )
        for control in (self.gui_scale, self.gui_route):
            control.on_update(lambda _: self.refresh(force=True))
        self.scene = client.scene
        self._nodes: dict[str, viser.LineSegmentsHandle] = {}
        self._shown: tuple[tuple[object, ...], tuple[object, ...]] | None = None
        self.refresh()

    @property
    def actor(self) -> str:
        return self.session.actor

    def _start(self) -> None:
        self.site.survey_start(str(self.gui_robot.value), actor=self.actor)

    def _accept_one(self) -> None:
        self.site.survey_accept([int(self.gui_id.value)], actor=self.actor)

    def _run(self, step: Callable[[], object]) -> None:
        try:
            step()
        except (KeyError, ValueError, RuntimeError) as exc:
            self.notify("Survey", str(exc))
        self.refresh(force=True)

    def _draw(self, name: str, segments: FloatArray, color: RGB, thickness: float) -> None:
        node = self._nodes.get(name)
        if node is not None:
            node.remove()
        if len(segments):
            self._nodes[name] = self.scene.add_line_segments(
                f"/survey/{name}", segments.astype(np.float32), color, thickness=thickness
            )
        else:
            self._nodes.pop(name, None)

    def refresh(self, *, force: bool = False) -> None:
        """Show the survey's state (cheap when unchanged); call at a few hertz. The scene
        is redrawn only when the estimate, the route or the drawing options changed."""
        st = self.site.survey_status()
        lms = self.site.landmarks()
        text_key = (st.state, st.blinks, st.message, st.accepted, st.drive_s, len(lms))
        scene_key = (
            st.state,
            st.estimates,
            st.accepted,
            st.proposals,
            st.route,
            len(lms),
            float(self.gui_scale.value),
            bool(self.gui_route.value),
        )
        if (text_key, scene_key) == self._shown and not force:
            return
        redraw = force or self._shown is None or scene_key != self._shown[1]
        self._shown = (text_key, scene_key)
        driving = st.state == "driving"
        self.gui_start.disabled = st.state in ("driving", "solving")
        self.gui_stop.disabled = not driving
        self.gui_cancel.disabled = st.state == "idle"
        can_accept = bool(st.proposals) and st.state in ("driving", "done", "interrupted")
        self.gui_accept_one.disabled = not can_accept
        self.gui_accept_all.disabled = not can_accept
        self.gui_progress.content = progress_text(st, len(lms))
        if not redraw:
            return
        self.gui_table.content = proposals_table(st.proposals)
        segs = survey_segments(st, lms, float(self.gui_scale.value))
        for state, color in SURVEY_STATE_COLORS.items():
            self._draw(state, segs[state], color, 0.06 if state != "unseen" else 0.04)
        route = np.zeros((0, 2, 3))
        if st.route and self.gui_route.value and driving:
            start = self._robot_xy(st.robot)
            pts = np.array([*([start] if start is not None else []), *st.route])
            route = polyline_segments(np.column_stack([pts, np.full(len(pts), ROUTE_Z_M)]))
        self._draw("route", route, ROUTE_COLOR, 0.06)

    def _robot_xy(self, name: str | None) -> tuple[float, float] | None:
        for r in self.site.robots():
            if r.name == name and r.pose is not None:
                return (r.pose.x, r.pose.y)
        return None
