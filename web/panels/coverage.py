"""The coverage view: colour this browser's floor by landmarks in view or expected error,
and flag landmark pairs spaced outside the paper's range.

It uses the camera (lens and mounting) of the robot chosen in the panel, says so, and is
recomputed when the map changes (a landmark added, moved or deleted, a map imported)."""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
import viser

from commissioning.coverage import CoverageConfig, coverage_grid, spacing_flags
from web.scene import draw_coverage
from web.services import LandmarkState, ViewerSite

CHOICES = ("off", "landmarks in view", "expected error")


class CoveragePanel:
    """Coverage controls; the layer is drawn in this browser's scene only."""

    def __init__(
        self, client: viser.ClientHandle, site: ViewerSite, notify: Callable[[str, str], None]
    ) -> None:
        self.client, self.site, self.notify = client, site, notify
        gui = client.gui
        names = [r.name for r in site.robots()] or ["-"]
        with gui.add_folder("Coverage", expand_by_default=False):
            self.gui_by = gui.add_dropdown("Colour floor by", CHOICES)
            self.gui_robot = gui.add_dropdown("Robot (its camera)", names)
            self.gui_step = gui.add_number("Grid step (m)", 0.25, min=0.05, max=2.0, step=0.05)
            self.gui_text = gui.add_markdown("")
        self.gui_by.on_update(self._on_choice)
        self.gui_robot.on_update(self._on_choice)
        self._map_key: tuple[tuple[int, float, float, float], ...] | None = None

    def _on_choice(self, _event: object) -> None:
        self.show()

    def refresh(self, landmarks: Sequence[LandmarkState]) -> bool:
        """Recompute a shown layer when the map changed; True when it did (call at a few
        hertz with the site's landmarks)."""
        key = tuple((lm.id, lm.x, lm.y, lm.z) for lm in landmarks)
        if key == self._map_key:
            return False
        first = self._map_key is None
        self._map_key = key
        if first or self.gui_by.value == "off":
            return False
        self.show()
        return True

    def show(self) -> str:
        """Compute and draw the chosen layer; returns the summary shown in the panel."""
        by = self.gui_by.value
        if by == "off":
            draw_coverage(self.client.scene, None, [], {})
            self.gui_text.content = ""
            return ""
        robots = self.site.robots()
        lms = self.site.landmarks()
        names = tuple(r.name for r in robots)
        if names and tuple(self.gui_robot.options) != names:
            self.gui_robot.options = names
        robot = next((r for r in robots if r.name == self.gui_robot.value), None)
        if robot is None or not lms:
            self.gui_text.content = "needs a robot (for its camera) and landmarks"
            return self.gui_text.content
        ids = np.array([lm.id for lm in lms])
        pos = np.array([[lm.x, lm.y, lm.z] for lm in lms])
        try:
            cov = coverage_grid(robot.camera, pos, CoverageConfig(step_m=self.gui_step.value))
        except ValueError as exc:
            self.notify("Coverage", str(exc))
            return str(exc)
        flags = spacing_flags(ids, pos)
        draw_coverage(
            self.client.scene,
            cov,
            flags,
            dict(zip(ids.tolist(), pos, strict=True)),
            by="error" if by == "expected error" else "count",
        )
        n = cov.counts.size
        dead = int(np.sum(cov.counts == 0))
        one = int(np.sum(cov.counts == 1))
        med = np.nanmedian(cov.error_m) if np.any(np.isfinite(cov.error_m)) else float("nan")
        lines = [
            f"with the camera of **{robot.name}**, for the map of {len(lms)} landmarks: "
            f"{n} points, {100 * dead / n:.0f} % see no landmark, {100 * one / n:.0f} % only "
            f"one; median expected error {100 * med:.1f} cm",
        ]
        lines += [
            f"- pair {f.a}-{f.b}: {100 * f.distance_m:.0f} cm, {f.problem.replace('_', ' ')}"
            f" (allowed {100 * f.allowed_m[0]:.0f}-{100 * f.allowed_m[1]:.0f} cm)"
            for f in flags[:20]
        ]
        self.gui_text.content = "\n".join(lines)
        return self.gui_text.content
