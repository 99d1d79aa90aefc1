"""`SiteAdapter`: the server's `SiteServices` seen through the viewer's `ViewerSite` protocol.

Reads go to the map repository (cached until its change listener fires), the robot registry,
the gateway and the battery log (cached for `battery_ttl_s`); actions go through the same
data layer and audit log as the REST API, with the viewer user as the actor. LED commands
and discovery are coroutines on the server's loop, awaited here with `services.call`.

Every pose update of every robot reaches the adapter through a subscription to the pose bus
(drained whenever the viewer reads the robots): it keeps each robot's recent estimates (the
wizard takes the one for its frame, `pose_at`) and feeds the doubt tracker (`web.doubt`) with
the LEDs as they were at each frame's time: it listens to every LED state the gateway
publishes (`web.led_timeline`).
"""

from __future__ import annotations

import statistics
import threading
import time
from collections import deque
from typing import Any

import numpy as np

from localizer.camera import CameraModel, sensor_from_camera
from localizer.events import LedsChanged, PoseEstimate
from localizer.spots import DetectionConfig, detect_spots
from rf_gateway.errors import LandmarkUnreachableError, RfGatewayError
from server.errors import UnavailableError
from server.led_schedule.status import site_energy
from web.candidates import doubted_candidates, new_radio_candidates
from web.doubt import Doubt, DoubtConfig, DoubtTracker
from web.led_timeline import LedTimeline
from web.services import (
    CameraView,
    Candidate,
    EventLine,
    FramePose,
    LandmarkState,
    RobotState,
)


class SiteAdapter:
    """Implements `web.services.ViewerSite` over `server.services.SiteServices`.

    Args:
        services: the running site's `SiteServices`.
        battery_ttl_s: battery readings are re-read from the database this often, seconds.
        detection: spot detector settings for the camera view.
        doubt: when a landmark counts as doubted.
        pose_history: estimates kept per robot for `pose_at` (frames).
    """

    def __init__(
        self,
        services: Any,
        *,
        battery_ttl_s: float = 10.0,
        detection: DetectionConfig | None = None,
        doubt: DoubtConfig | None = None,
        pose_history: int = 300,
    ) -> None:
        self.services = services
        self.battery_ttl_s = battery_ttl_s
        self.detection = detection or DetectionConfig()
        self._lock = threading.Lock()
        self._pose_lock = threading.Lock()
        self._map_cache: list[Any] | None = None
        self._battery: dict[int, tuple[float, Any]] = {}
        self._view: CameraView | None = None
        self._doubt = DoubtTracker(doubt)
        self._history: dict[str, deque[Any]] = {}
        self._pose_history = pose_history
        services.map.add_listener(self._on_map_changed)
        self._leds = LedTimeline()
        self._led_lock = threading.Lock()  # the gateway's listener runs on the server's loop
        self._gateway: Any = None
        self._listen_to_leds()
        self._poses = services.subscribe_poses(maxsize=4096)

    def close(self) -> None:
        """Stop listening to map changes, LED states and pose updates."""
        self.services.map.remove_listener(self._on_map_changed)
        if self._gateway is not None:
            self._gateway.remove_led_listener(self._on_leds)
        self._poses.close()

    def _listen_to_leds(self) -> None:
        """Subscribe to the gateway's LED states once there is a gateway."""
        if self._gateway is None and getattr(self.services, "gateway", None) is not None:
            self._gateway = self.services.gateway
            self._gateway.add_led_listener(self._on_leds)
            if self._gateway.leds is not None:
                self._on_leds(self._gateway.leds)

    def _on_leds(self, event: LedsChanged) -> None:
        """Every LED state the gateway publishes (on the server's loop)."""
        landmarks = self._gateway.landmarks  # what all_lit means
        with self._led_lock:
            self._leds.add(event, landmarks)

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
            with self._pose_lock:
                self._doubt.set_map({lm.id: (lm.x, lm.y, lm.z) for lm in cached})
        return cached

    def _drain(self) -> None:
        """Take the pose updates published since the last call: history and doubt."""
        self._map()  # the doubt tracker needs the current map
        self._listen_to_leds()
        with self._pose_lock:
            updates = self._poses.drain()
            if not updates:
                return
            cameras = {r.name: r.camera for r in self.services.robots.runners()}
            quiet_s = self._doubt.config.led_quiet_s
            for upd in updates:
                q = self._history.get(upd.robot)
                if q is None:
                    q = self._history[upd.robot] = deque(maxlen=self._pose_history)
                q.append(upd)
                pose = _estimate(upd)
                if pose is None:
                    self._doubt.unlocalized(upd.robot)
                    continue
                camera = cameras.get(upd.robot)
                with self._led_lock:
                    leds = self._leds.at(upd.t_ns, quiet_s=quiet_s)  # at the frame's time
                if camera is not None and leds is not None:
                    self._doubt.observe(upd.robot, camera, pose, leds.lit, unsure=leds.unsure)

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
        self._drain()
        with self._pose_lock:
            doubted = self._doubt.doubted()
        out = []
        energy = site_energy(
            self.services, lambda i: getattr(self._battery_of(i), "supply_mv", None)
        )
        for lm in self._map():
            b = self._battery_of(lm.id)
            e = energy.landmark(lm.id)
            out.append(
                LandmarkState(
                    id=lm.id, x=lm.x, y=lm.y, z=lm.z, locked=lm.locked, radio=lm.radio,
                    supply_mv=None if b is None else b.supply_mv,
                    percent=None if b is None else b.percent,
                    days_left=None if b is None else b.days_left,
                    reachable=lm.id not in unreachable, doubted=lm.id in doubted,
                    lit=e.lit, lit_reason=e.reason, duty=e.duty, model_days=e.days_left,
                    low=e.low,
                )
            )  # fmt: skip
        return out

    def robots(self) -> list[RobotState]:
        self._drain()
        now = self.services.clock_ns()
        out = []
        for runner in self.services.robots.runners():
            upd = runner.latest
            pose = None if upd is None else _estimate(upd)
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

    def pose_at(self, robot: str, t_ns: int) -> FramePose | None:
        self._drain()
        with self._pose_lock:
            hist = list(self._history.get(robot, ()))
        upd = next((u for u in reversed(hist) if u.t_ns == t_ns), None)
        pose = None if upd is None else _estimate(upd)
        if pose is None:
            return None
        fixes = [u.t_ns for u in hist if u.mode == "landmark" and u.x is not None]
        last_fix = max((t for t in fixes if t <= t_ns), default=None)
        if last_fix is None:  # older than the history: the runner's own record
            runner_fix = self.services.robots.get(robot).last_fix_t_ns
            last_fix = runner_fix if runner_fix is not None and runner_fix <= t_ns else None
        return FramePose(pose, last_fix)

    # -- actions -----------------------------------------------------------------------------
    def relocalize(self, robot: str, *, actor: str) -> None:
        self.services.relocalize(robot)

    def store_camera(self, robot: str, camera: CameraModel, *, actor: str) -> None:
        sensor = sensor_from_camera(camera)

        async def store() -> None:  # on the server's loop, as the REST route does it
            self.services.store_robot_camera(robot, sensor)

        self.services.call(store(), timeout_s=30.0)

    def set_leds(self, lit: frozenset[int], *, actor: str) -> frozenset[int]:
        try:
            self.services.call(self.services.set_leds(frozenset(lit)), timeout_s=30.0)
        except LandmarkUnreachableError as exc:  # the others were switched
            gw = self.services.gateway
            return frozenset({exc.landmark_id}) | (gw.unreachable if gw is not None else set())
        return frozenset()

    def set_radio_led(self, address: str, on: bool, *, actor: str) -> None:
        try:
            self.services.call(self.services.radio_led(address, on), timeout_s=30.0)
        except (RfGatewayError, UnavailableError, TimeoutError) as exc:
            raise ValueError(f"radio {address} did not switch its LED: {exc}") from exc

    def hold_leds(self, held: bool) -> None:
        """Keep the robots' LED requests off the radio while the wizard drives the LEDs."""
        self.services.hold_leds(held)

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
        from server.models import LandmarkCreate

        data = LandmarkCreate(id=landmark_id, x=x, y=y, z=z, radio=radio)
        lm = self.services.map.create(data, actor=actor)
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

    def doubt(self, landmark_id: int) -> Doubt:
        """A landmark's chances and uses so far (`web.doubt.DoubtTracker.record`)."""
        self._drain()
        with self._pose_lock:
            return self._doubt.record(landmark_id)

    def to_identify(self, *, discover: bool = False) -> list[Candidate]:
        """Doubted unlocked landmarks, then (with `discover`) the radios a node discovery
        finds that are not in the map (`SiteServices.discover`, as `POST /radio/discover`)."""
        self._drain()
        lms = self._map()
        with self._pose_lock:
            doubted = self._doubt.doubted()
        out = doubted_candidates(doubted, {lm.id for lm in lms if lm.locked})
        if discover:
            try:
                radios = self.services.call(self.services.discover(), timeout_s=60.0)
            except (RfGatewayError, UnavailableError, TimeoutError) as exc:
                raise ValueError(f"radio discovery failed: {exc}") from exc
            known = {lm.radio for lm in lms if lm.radio}
            found = [(r.address, r.node_id) for r in radios if r.address not in known]
            out += new_radio_candidates(found, {lm.id for lm in lms})
        return out


def _estimate(upd: Any) -> PoseEstimate | None:
    """A `PoseUpdate` as the localizer's estimate; None when it carries no pose."""
    if upd.x is None or upd.y is None or upd.theta is None:
        return None
    cov = np.zeros((3, 3)) if upd.covariance is None else np.asarray(upd.covariance)
    ids = tuple(int(i) for i in upd.landmark_ids)
    return PoseEstimate(upd.t_ns, upd.x, upd.y, upd.theta, cov, upd.mode, ids)
