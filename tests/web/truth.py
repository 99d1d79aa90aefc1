"""`TruthPoseSite`: the real site (`SiteAdapter` over the running `SiteServices`) with each
robot's pose taken from the virtual site's truth instead of its localizer.

The wizard's tests check the viewer (LEDs switched through the real gateway and simulated
radio, frames rendered by the simulator with the world's LEDs as they are, spots found by
the real detector, positions saved through the real data layer), not the localizer, whose
accuracy has its own tests. Each camera view is rendered from the robot's true pose at that
moment, and `robots()` reports that same pose, so pose and frame agree exactly.
"""

from __future__ import annotations

import threading
from dataclasses import replace
from typing import Any

import numpy as np

from localizer.geometry import T_world_body_from_pose
from localizer.spots import DetectionConfig, detect_spots
from sim.render import render_frame
from web.services import CameraView, RobotState


class TruthPoseSite:
    def __init__(self, inner: Any, services: Any) -> None:
        self.inner, self.services, self.sim = inner, services, services.sim
        self._lock = threading.Lock()
        self._poses: dict[str, tuple[float, float, float]] = {}
        self._rng = np.random.default_rng(11)
        self.led_log: list[frozenset[int]] = []
        self.lit_log: list[frozenset[int]] = []

    def lit(self) -> frozenset[int]:
        lit = self.inner.lit()
        self.lit_log.append(lit)
        return lit

    def set_leds(self, lit: frozenset[int], *, actor: str) -> None:
        self.led_log.append(frozenset(lit))
        self.inner.set_leds(lit, actor=actor)

    def __getattr__(self, name: str) -> Any:
        return getattr(self.inner, name)

    def robots(self) -> list[RobotState]:
        out = []
        for rb in self.inner.robots():
            with self._lock:
                x, y, th = self._poses.get(rb.name) or self.sim.true_pose(rb.name)
            from localizer.events import PoseEstimate

            pose = PoseEstimate(rb.now_ns, x, y, th, np.diag([1e-6, 1e-6, 1e-6]), "landmark")
            out.append(replace(rb, pose=pose, mode="landmark", last_fix_t_ns=rb.now_ns))
        return out

    def camera_view(self, robot: str) -> CameraView | None:
        pose = self.sim.true_pose(robot)
        T = T_world_body_from_pose(*pose)
        cam = self.sim.rig(robot).camera_true
        sources, intensities = self.sim.world.point_sources((T @ cam.T_body_camera)[:3, 3])
        with self._lock:
            image = render_frame(
                cam, T, sources, intensities, rng=self._rng, config=self.sim.scenario.render,
                extended=self.sim.world.extended,
            )  # fmt: skip
            self._poses[robot] = pose
        spots = detect_spots(image, DetectionConfig())
        order = np.argsort(-spots.intensities)
        return CameraView(self.services.clock_ns(), image, spots.pixels[order])
