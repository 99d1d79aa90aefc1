"""`SiteAdapter`: the server's `SiteServices` seen through the viewer's `ViewerSite` protocol.

Reads go to the map repository (cached until its change listener fires), the robot registry,
the gateway and the battery log (cached for `battery_ttl_s`); actions go through the same
data layer and audit log as the REST API, with the viewer user as the actor. LED commands
are coroutines on the server's loop, awaited here with `services.call`.
"""

from __future__ import annotations

import statistics
import threading
import time
from collections.abc import Sequence
from typing import Any

import numpy as np

from localizer.camera import CameraModel, sensor_from_camera
from localizer.events import PoseEstimate
from localizer.spots import DetectionConfig, detect_spots
from web.services import CameraView, EventLine, LandmarkState, RobotState


class SiteAdapter:
    """Implements `web.services.ViewerSite` over `server.services.SiteServices`.

    Args:
        services: the running site's `SiteServices`.
        battery_ttl_s: battery readings are re-read from the database this often, seconds.
        detection: spot detector settings for the camera view.
    """

    def __init__(
        self,
        services: Any,
        *,
        battery_ttl_s: float = 10.0,
        detection: DetectionConfig | None = None,
    ) -> None:
        self.services = services
        self.battery_ttl_s = battery_ttl_s
        self.detection = detection or DetectionConfig()
        self._lock = threading.Lock()
        self._map_cache: list[Any] | None = None
        self._battery: dict[int, tuple[float, Any]] = {}
        self._seen: set[int] = set()
        self._view: CameraView | None = None
        self._parked: Any = None
        services.map.add_listener(self._on_map_changed)

    def close(self) -> None:
        """Stop listening to map changes."""
        self.services.map.remove_listener(self._on_map_changed)

    def _on_map_changed(self, _landmarks: list[Any]) -> None:
        with self._lock:
            self._map_cache = None

    def _map(self) -> list[Any]:
        with self._lock:
            cached = self._map_cache
        if cached is None:
            cached = self.services.map.list()
            with self._lock:
                self._map_cache = cached
        return cached

    def _battery_of(self, landmark_id: int) -> Any:
        now = time.monotonic()
        hit = self._battery.get(landmark_id)
        if hit is not None and now - hit[0] < self.battery_ttl_s:
            return hit[1]
        try:
            status = self.services.battery(landmark_id)
        except KeyError:
            return None
        self._battery[landmark_id] = (now, status)
        return status

    # -- reads -----------------------------------------------------------------------------
    def landmarks(self) -> list[LandmarkState]:
        gw = self.services.gateway
        unreachable = gw.unreachable if gw is not None else frozenset()
        out = []
        for lm in self._map():
            b = self._battery_of(lm.id)
            out.append(
                LandmarkState(
                    id=lm.id, x=lm.x, y=lm.y, z=lm.z, locked=lm.locked, radio=lm.radio,
                    supply_mv=None if b is None else b.supply_mv,
                    percent=None if b is None else b.percent,
                    days_left=None if b is None else b.days_left,
                    reachable=lm.id not in unreachable, seen=lm.id in self._seen,
                )
            )  # fmt: skip
        return out

    def robots(self) -> list[RobotState]:
        now = self.services.clock_ns()
        out = []
        for runner in self.services.robots.runners():
            upd = runner.latest
            pose = None
            if upd is not None and upd.x is not None:
                cov = np.zeros((3, 3)) if upd.covariance is None else np.asarray(upd.covariance)
                ids = tuple(int(i) for i in upd.landmark_ids)
                self._seen.update(ids)
                pose = PoseEstimate(upd.t_ns, upd.x, upd.y, upd.theta, cov, upd.mode, ids)
            out.append(
                RobotState(runner.name, runner.camera, pose, str(runner.mode),
                           runner.last_fix_t_ns, now)
            )  # fmt: skip
        return out

    def lit(self) -> frozenset[int]:
        return frozenset(self.services.lit())

    def events(self, limit: int) -> list[EventLine]:
        return [
            EventLine(e.t.strftime("%Y-%m-%d %H:%M:%S"), e.kind, e.message)
            for e in self.services.events.recent(limit)
        ]

    def camera_view(self, robot: str) -> CameraView | None:
        try:
            frame = self.services.robots.get(robot).last_frame
        except KeyError:
            return None
        if frame is None:
            return None
        with self._lock:
            if self._view is not None and self._view.t_ns == frame.t_ns:
                return self._view
        spots = detect_spots(frame.image, self.detection)
        order = np.argsort(-spots.intensities)
        view = CameraView(frame.t_ns, frame.image, spots.pixels[order])
        with self._lock:
            self._view = view
        return view

    def ceiling_height(self) -> float:
        zs = [lm.z for lm in self._map()]
        return float(statistics.median(zs)) if zs else 2.5

    # -- actions -----------------------------------------------------------------------------
    def relocalize(self, robot: str, *, actor: str) -> None:
        self.services.relocalize(robot)

    def store_camera(self, robot: str, camera: CameraModel, *, actor: str) -> None:
        sensor = sensor_from_camera(camera)

        async def store() -> None:  # on the server's loop, as the REST route does it
            self.services.store_robot_camera(robot, sensor)

        self.services.call(store(), timeout_s=30.0)

    def set_leds(self, lit: frozenset[int], *, actor: str) -> None:
        self.services.call(self.services.set_leds(frozenset(lit)), timeout_s=30.0)

    def hold_leds(self, held: bool) -> None:
        """Keep the robots' LED requests off the radio while the wizard drives the LEDs.

        Uses `services.hold_leds(held)` when the server offers it; until then (stopgap) it
        parks the live site's LED coordinator (`services.site.leds`), so robots' requests
        are dropped (their identification times out and retries) while confirmed LED
        changes still reach every localizer.
        """
        if hasattr(self.services, "hold_leds"):
            self.services.hold_leds(held)
            return
        site = getattr(self.services, "site", None)
        if site is None or not hasattr(site, "leds"):
            return
        with self._lock:
            if held and self._parked is None and site.leds is not None:
                self._parked, site.leds = site.leds, None
            elif not held and self._parked is not None:
                site.leds, self._parked = self._parked, None

    def add_landmark(
        self, landmark_id: int, x: float, y: float, z: float, *, actor: str
    ) -> LandmarkState:
        from server.models import LandmarkCreate

        lm = self.services.map.create(LandmarkCreate(id=landmark_id, x=x, y=y, z=z), actor=actor)
        return LandmarkState(lm.id, lm.x, lm.y, lm.z, lm.locked, lm.radio)

    def update_landmark(
        self,
        landmark_id: int,
        *,
        actor: str,
        x: float | None = None,
        y: float | None = None,
        z: float | None = None,
        locked: bool | None = None,
    ) -> LandmarkState:
        from server.models import LandmarkUpdate

        fields = {
            k: v for k, v in {"x": x, "y": y, "z": z, "locked": locked}.items() if v is not None
        }
        update = LandmarkUpdate.model_validate(fields)  # unset fields are kept
        lm = self.services.map.update(landmark_id, update, actor=actor)
        return LandmarkState(lm.id, lm.x, lm.y, lm.z, lm.locked, lm.radio)

    def delete_landmark(self, landmark_id: int, *, actor: str) -> None:
        self.services.map.delete(landmark_id, actor=actor)

    def undo_last(self, *, actor: str) -> str:
        rec = self.services.map.undo_last(actor=actor)
        if rec is None:
            raise ValueError("nothing to undo")
        return f"undid {rec.action} of landmark {rec.landmark_id} by {rec.actor}"

    def to_identify(self) -> Sequence[int]:
        """Unlocked landmarks no robot has used for a fix since the viewer started."""
        return [lm.id for lm in self._map() if not lm.locked and lm.id not in self._seen]
