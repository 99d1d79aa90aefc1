"""`SiteAdapter`: the server's `SiteServices` seen through the viewer's `ViewerSite` protocol.

Reads go to the map repository (cached until its change listener fires), the robot registry,
the LED facade and the battery log (cached for `battery_ttl_s`); actions go through the same
data layer and audit log as the REST API, with the viewer user as the actor. LED commands
and discovery are coroutines on the server's loop, awaited here with `services.call`.
Doubted landmarks and the identification wizard are the server's
(`services.commissioning`, the same as `/api/v1/commissioning/...`): the viewer only shows
and drives them.
"""

from __future__ import annotations

import statistics
import threading
import time
from collections.abc import Sequence

import numpy as np

from commissioning.doubt import Doubt
from commissioning.wizard import WizardStatus
from live.cells import CellsReplaced, replace_cells
from live.facades import BatteryStatus, Recordings
from live.leds.status import site_energy
from live.services import SiteServices
from live.survey.service import SurveyStatus
from live.upkeep_service import MapUpkeepService
from localizer.camera import CameraModel, sensor_from_camera
from localizer.spots import DetectionConfig, detect_spots
from rf_gateway.errors import LandmarkUnreachableError, RfGatewayError
from store.errors import UnavailableError
from store.floorplan import FloorPlanStore
from store.landmarks import MapRepository
from store.models import LandmarkCreate, LandmarkPublic, LandmarkUpdate
from store.zones import PoseHistory, ZoneStore
from web.panels.monitor import local_time_text
from web.services import (
    CameraView,
    Candidate,
    EventLine,
    LandmarkState,
    RobotState,
)


class SiteAdapter:
    """Implements `web.services.ViewerSite` over `live.services.SiteServices`.

    Args:
        services: the running site's `SiteServices`.
        battery_ttl_s: battery readings are re-read from the database this often, seconds.
        detection: spot detector settings for the camera view.
    """

    def __init__(
        self,
        services: SiteServices,
        *,
        battery_ttl_s: float = 10.0,
        detection: DetectionConfig | None = None,
    ) -> None:
        self.services = services
        self.battery_ttl_s = battery_ttl_s
        self.detection = detection or DetectionConfig()
        self._lock = threading.Lock()
        self._map_cache: list[LandmarkPublic] | None = None
        self._battery: dict[int, tuple[float, BatteryStatus]] = {}
        self._view: CameraView | None = None
        self.shown_floor: str | None = None
        """The floor whose landmarks and robots are shown (None: every floor)."""
        services.map.add_listener(self._on_map_changed)

    def close(self) -> None:
        """Stop listening to map changes."""
        self.services.map.remove_listener(self._on_map_changed)

    def _on_map_changed(self, _landmarks: list[LandmarkPublic]) -> None:
        with self._lock:
            self._map_cache = None

    def _map(self) -> list[LandmarkPublic]:
        with self._lock:
            cached = self._map_cache
        if cached is None:
            cached = self.services.map.list()
            with self._lock:
                self._map_cache = cached
        return cached

    def _battery_of(self, landmark_id: int) -> BatteryStatus | None:
        now = time.monotonic()
        hit = self._battery.get(landmark_id)
        if hit is not None and now - hit[0] < self.battery_ttl_s:
            return hit[1]
        try:
            status = self.services.leds.battery(landmark_id)
        except KeyError:
            return None
        self._battery[landmark_id] = (now, status)
        return status

    # -- reads -----------------------------------------------------------------------------
    def landmarks(self) -> list[LandmarkState]:
        unreachable = self.services.leds.unreachable
        doubted = self.services.commissioning.doubted()
        out = []
        energy = site_energy(
            self.services, lambda i: getattr(self._battery_of(i), "supply_mv", None)
        )
        for lm in self._map():
            if self.shown_floor is not None and lm.floor != self.shown_floor:
                continue
            b = self._battery_of(lm.id)
            e = energy.landmark(lm.id)
            out.append(
                LandmarkState(
                    id=lm.id,
                    x=lm.x,
                    y=lm.y,
                    z=lm.z,
                    locked=lm.locked,
                    radio=lm.radio,
                    supply_mv=None if b is None else b.supply_mv,
                    percent=None if b is None else b.percent,
                    days_left=None if b is None else b.days_left,
                    reachable=lm.id not in unreachable,
                    doubted=lm.id in doubted,
                    lit=e.lit,
                    lit_reason=e.reason,
                    duty=e.duty,
                    model_days=e.days_left,
                    low=e.low,
                    sigma_m=lm.sigma_m,
                )
            )
        return out

    def robots(self) -> list[RobotState]:
        now = self.services.clock_ns()
        out = []
        for runner in self.services.robots.runners():
            if self.shown_floor is not None and runner.floor != self.shown_floor:
                continue
            upd = runner.latest
            pose = None if upd is None else upd.estimate()
            out.append(
                RobotState(
                    runner.name,
                    runner.camera,
                    pose,
                    str(runner.mode),
                    runner.last_fix_t_ns,
                    now,
                    runner.reasons.reason_text,
                    runner.reasons.quality,
                )
            )
        return out

    def lit(self) -> frozenset[int]:
        return frozenset(self.services.leds.lit())

    def events(self, limit: int) -> list[EventLine]:
        return [
            EventLine(local_time_text(e.t), e.kind, e.message)
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

    def map_history(self) -> MapRepository:
        return self.services.map

    def map_proposals(self) -> MapUpkeepService:
        return self.services.upkeep

    def floorplan(self) -> FloorPlanStore:
        return self.services.floorplans.of(self.shown_floor)

    def zones(self) -> ZoneStore:
        return self.services.zones

    def pose_history(self) -> PoseHistory:
        return self.services.pose_history

    def recordings(self) -> Recordings:
        return self.services.recordings

    def ceiling_height(self) -> float:
        zs = [lm.z for lm in self._map() if self.shown_floor in (None, lm.floor)]
        return float(statistics.median(zs)) if zs else 2.5

    def floors(self) -> list[tuple[str, str]]:
        return [(f.id, f.name) for f in self.services.floors.list()]

    def show_floor(self, floor: str | None) -> None:
        if floor is not None:
            self.services.floors.get(floor)  # NotFoundError naming it
        self.shown_floor = floor

    def floor_shown(self) -> str | None:
        return self.shown_floor

    def elsewhere(self) -> list[tuple[str, str]]:
        shown = self.shown_floor
        if shown is None:
            return []
        return [(r.name, r.floor) for r in self.services.robots.runners() if r.floor != shown]

    # -- actions -----------------------------------------------------------------------------
    def relocalize(self, robot: str, *, actor: str) -> None:
        self.services.robots.relocalize(robot)

    def store_camera(self, robot: str, camera: CameraModel, *, actor: str) -> None:
        sensor = sensor_from_camera(camera)

        async def store() -> None:  # on the server's loop, as the REST route does it
            self.services.robots.store_camera(robot, sensor)

        self.services.call(store(), timeout_s=30.0)

    def set_leds(self, lit: frozenset[int], *, actor: str) -> frozenset[int]:
        try:
            self.services.call(self.services.leds.set_leds(frozenset(lit)), timeout_s=30.0)
        except LandmarkUnreachableError as exc:  # the others were switched
            return frozenset({exc.landmark_id}) | self.services.leds.unreachable
        return frozenset()

    def add_landmark(
        self,
        landmark_id: int,
        x: float,
        y: float,
        z: float,
        *,
        actor: str,
        radio: str | None = None,
    ) -> LandmarkState:
        data = LandmarkCreate(id=landmark_id, x=x, y=y, z=z, radio=radio)
        lm = self.services.map.create(data, actor=actor)
        return LandmarkState(lm.id, lm.x, lm.y, lm.z, lm.locked, lm.radio, sigma_m=lm.sigma_m)

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
        fields = {
            k: v for k, v in {"x": x, "y": y, "z": z, "locked": locked}.items() if v is not None
        }
        update = LandmarkUpdate.model_validate(fields)  # unset fields are kept
        lm = self.services.map.update(landmark_id, update, actor=actor)
        return LandmarkState(lm.id, lm.x, lm.y, lm.z, lm.locked, lm.radio, sigma_m=lm.sigma_m)

    def delete_landmark(self, landmark_id: int, *, actor: str) -> None:
        self.services.map.delete(landmark_id, actor=actor)

    def replace_cells(self, landmark_id: int, *, actor: str) -> CellsReplaced:
        done = self.services.call(
            replace_cells(self.services, landmark_id, actor=actor), timeout_s=60.0
        )
        self._battery.pop(landmark_id, None)  # the next refresh reads the new status
        return done

    def doubt(self, landmark_id: int) -> Doubt:
        """A landmark's chances and uses so far (`commissioning.doubt`)."""
        return self.services.commissioning.doubt(landmark_id)

    def to_identify(self, *, discover: bool = False) -> list[Candidate]:
        """Doubted unlocked landmarks, then (with `discover`) the radios a node discovery
        finds that are not in the map (as `POST /commissioning/candidates/discover`)."""
        radios = self.services.leds.discovered
        if discover:
            try:
                radios = self.services.call(self.services.leds.discover(), timeout_s=60.0)
            except (RfGatewayError, UnavailableError, TimeoutError) as exc:
                raise ValueError(f"radio discovery failed: {exc}") from exc
        found = [(r.address, r.node_id) for r in radios]
        return self.services.commissioning.to_identify(found)

    # -- the identification wizard (the server's: `services.commissioning`) ------------------
    def wizard_status(self) -> WizardStatus:
        return self.services.commissioning.status()

    def wizard_start(self, robot: str, queue: Sequence[Candidate], *, actor: str) -> None:
        self.services.commissioning.start_wizard(robot, queue, actor=actor)

    def wizard_confirm(
        self,
        *,
        actor: str,
        position: tuple[float, float, float] | None = None,
        accept_far: bool = False,
    ) -> None:
        self.services.commissioning.confirm(actor=actor, position=position, accept_far=accept_far)

    def wizard_skip(self, *, actor: str) -> None:
        self.services.commissioning.skip(actor=actor)

    def wizard_switch_anyway(self, *, actor: str) -> None:
        self.services.commissioning.switch_anyway(actor=actor)

    def wizard_cancel(self, *, actor: str) -> None:
        self.services.commissioning.cancel(actor=actor)

    # -- the live survey (the server's: `services.survey`) -----------------------------------
    def survey_status(self) -> SurveyStatus:
        return self.services.survey.status()

    def survey_start(self, robot: str, *, actor: str) -> None:
        self.services.survey.start(robot, actor=actor)

    def survey_stop(self, *, actor: str) -> None:
        self.services.survey.stop(actor=actor)

    def survey_cancel(self, *, actor: str) -> None:
        self.services.survey.cancel(actor=actor)

    def survey_accept(self, landmark_ids: Sequence[int] | None, *, actor: str) -> None:
        ids = None if landmark_ids is None else list(landmark_ids)
        self.services.survey.accept(ids, actor=actor)
