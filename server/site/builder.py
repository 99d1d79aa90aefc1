"""The live site: builds the virtual site (if any), the radio gateway, the LED coordinator
and one `RobotRunner` per robot, and runs the site clock.

Threads: the site clock thread steps the virtual site at its camera rate and feeds each
robot's frames and odometry to its localizer; camera sources have their own threads; the
gateway, the LED coordinator and the battery poll run on the server's event loop.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import queue
import threading
from typing import TYPE_CHECKING, Any

from localizer.camera import camera_from_sensor, sensor_from_camera
from localizer.events import FrameObserved, Mode
from localizer.robot import RobotGeometry
from rf_gateway.battery import BatteryConfig
from rf_gateway.config import GatewayConfig
from rf_gateway.errors import RfGatewayError
from rf_gateway.events import (
    LandmarkReachable,
    LandmarkUnreachable,
    LowBattery,
    TransportStateChanged,
)
from rf_gateway.gateway import Gateway
from server.crud.landmarks import parse_map_json
from server.models import LandmarkPublic, RobotCreate, RobotPublic
from server.site.leds import LedCoordinator
from server.site.robot import RobotRunner, make_localizer
from server.site.serial_sink import SerialSink
from server.site.serial_wheels import SerialWheelSource
from server.site.sources import CameraSource

if TYPE_CHECKING:
    from server.services import SiteServices

log = logging.getLogger(__name__)
SITE_STEP_HZ = 100.0
MAX_FRAME_LAG_S = 0.25
SHUTDOWN_LEDS_TIMEOUT_S = 5.0


def _sample_parts(sample: Any) -> tuple[str, Any]:
    """(robot name, localizer event) of one `sim.live` sensor sample."""
    return sample.robot, sample.event


class LiveSiteRunner:
    """Start and stop everything live for `services`."""

    def __init__(self, services: SiteServices) -> None:
        self.services = services
        self.settings = services.settings
        self.sim: Any = None
        self.gateway: Gateway | None = None
        self.leds: LedCoordinator | None = None
        self.cameras: dict[str, CameraSource] = {}
        self.wheels: dict[str, SerialWheelSource] = {}
        self._stop = threading.Event()
        self._clock: threading.Thread | None = None
        self._worker: threading.Thread | None = None
        self._samples: queue.SimpleQueue[list[Any] | None] = queue.SimpleQueue()
        self.frames_skipped = 0
        self.serial: SerialSink | None = None
        self._tasks: list[asyncio.Task[None]] = []
        self._loop: asyncio.AbstractEventLoop | None = None

    # -- start -----------------------------------------------------------------------------
    async def start(self) -> None:
        s = self.services
        self._loop = asyncio.get_running_loop()
        if self.settings.radio == "sim":
            self.sim = self._build_sim()
            s.sim = self.sim
        if self.sim is not None:
            self._adopt_sim()
        await self._start_gateway()
        for robot in s.robot_store.list():
            if robot.source == "sim" and robot.name not in self._sim_names():
                continue
            self.start_robot(robot)
        if self.settings.serial_sink:
            robots = {self.settings.serial_robot} if self.settings.serial_robot else None
            sub = s.subscribe_poses(robots)
            self.serial = SerialSink.open(sub, self.settings.serial_sink, self.settings.serial_baud)
            self.serial.start()
        if self.sim is not None:
            self._clock = threading.Thread(target=self._run_clock, name="site-clock", daemon=True)
            self._worker = threading.Thread(
                target=self._run_localizers, name="site-localizers", daemon=True
            )
            self._clock.start()
            self._worker.start()

    def start_robot(self, robot: RobotPublic) -> RobotRunner:
        """Run (or restart with a new configuration) one robot's localizer and source."""
        s = self.services
        self.stop_robot(robot.name)
        geometry = RobotGeometry(robot.wheel_base, robot.max_speed)
        camera = camera_from_sensor(robot.camera, source=f"robot {robot.name} camera")
        runner = RobotRunner(
            robot.name,
            camera,
            geometry,
            make_localizer(camera, s.map.landmark_map(), geometry),
            publish=s.poses.publish,
            request_leds=self._request_leds,
            source=robot.source,
        )
        runner.on_mode_change = self._on_mode_change
        s.robots.add(runner)
        if robot.source == "camera" and robot.device:
            cam = CameraSource(runner, robot.device, s.clock_ns)
            cam.start()
            self.cameras[robot.name] = cam
        if robot.source == "camera" and robot.wheel_port:
            wheels = SerialWheelSource(runner, robot.wheel_port, robot.wheel_baud, s.clock_ns)
            wheels.start()
            self.wheels[robot.name] = wheels
        return runner

    def stop_robot(self, name: str) -> None:
        """Stop a robot's camera source (if any) and remove it from the registry."""
        cam = self.cameras.pop(name, None)
        if cam is not None:
            cam.stop()
        wheels = self.wheels.pop(name, None)
        if wheels is not None:
            wheels.stop()
        runner = self.services.robots.remove(name)
        if runner is not None:
            runner.stop_recording()

    def _build_sim(self) -> Any:
        from sim.live import LiveSite
        from sim.scenario import load_scenario

        return LiveSite(
            load_scenario(self.settings.scenario),
            seed=self.settings.seed,
            clock_ns=self.services.clock_ns,
        )

    def _sim_names(self) -> list[str]:
        return list(self.sim.robot_names) if self.sim is not None else []

    def _adopt_sim(self) -> None:
        """First start on a virtual site: take its surveyed map and its robots."""
        s = self.services
        if not s.map.list():
            items = parse_map_json(
                {"landmarks": self.sim.landmark_records()}, source="virtual site"
            )
            s.map.replace_all(items, actor="virtual site")
        known = {r.name for r in s.robot_store.list()}
        for name in self._sim_names():
            if name in known:
                continue
            geo = self.sim.robot_geometry(name)
            s.robot_store.upsert(
                RobotCreate(
                    name=name,
                    source="sim",
                    wheel_base=geo.wheel_base,
                    max_speed=geo.max_speed,
                    camera=sensor_from_camera(self.sim.camera(name)),
                )
            )

    async def _start_gateway(self) -> None:
        from rf_gateway.factory import make_transport

        s = self.services
        try:
            transport = make_transport(
                self.settings.radio, sim_radio=None if self.sim is None else self.sim.radio
            )
        except ValueError as exc:
            log.error("no radio: %s", exc)
            return
        config = GatewayConfig(battery=BatteryConfig(interval_s=None))
        self.gateway = Gateway(transport, s.map.addresses(), config, clock_ns=s.clock_ns)
        s.gateway = self.gateway
        await self.gateway.start()
        self.leds = LedCoordinator(self.gateway, s.robots.runners, self._on_led_error)
        self.leds.start()
        loop = asyncio.get_running_loop()
        self._tasks = [loop.create_task(self._gateway_events())]
        if self.settings.battery_interval_s is not None:
            self._tasks.append(loop.create_task(self._battery_loop()))

    # -- running ---------------------------------------------------------------------------
    def _run_clock(self) -> None:
        """Step the virtual site often (frames are rendered with the LEDs lit at the call,
        so a short period keeps a frame's picture true to its timestamp); the localizers
        run on another thread."""
        period = 1.0 / SITE_STEP_HZ
        while not self._stop.wait(period):
            try:
                samples = self.sim.step(self.services.clock_ns())
            except Exception:
                log.exception("virtual site step failed")
                continue
            if samples:
                self._samples.put(samples)
        self._samples.put(None)

    def _run_localizers(self) -> None:
        """Feed the virtual site's samples to the robots; frames older than
        `MAX_FRAME_LAG_S` when their turn comes are skipped (odometry never is)."""
        robots = self.services.robots
        while True:
            samples = self._samples.get()
            if samples is None:
                return
            for sample in samples:
                name, event = _sample_parts(sample)
                if isinstance(event, FrameObserved):
                    lag_s = (self.services.clock_ns() - event.t_ns) * 1e-9
                    if lag_s > MAX_FRAME_LAG_S:
                        self.frames_skipped += 1
                        continue
                with contextlib.suppress(KeyError):
                    robots.get(name).handle(event)

    def _request_leds(self, robot: str, req: Any) -> None:
        if self.leds is not None:
            self.leds.request(robot, req)

    def _on_led_error(self, robot: str, message: str) -> None:
        self.services.events.emit("led_request_failed", f"robot {robot}: {message}", robot=robot)

    def _on_mode_change(self, robot: str, old: Mode, new: Mode) -> None:
        if new == "lost":
            self.services.events.emit("robot_lost", f"robot {robot} is lost", robot=robot)
        elif new == "landmark" and old in ("lost", "identifying"):
            self.services.events.emit("robot_localized", f"robot {robot} localized", robot=robot)

    async def _gateway_events(self) -> None:
        assert self.gateway is not None
        emit = self.services.events.emit
        async for ev in self.gateway.subscribe_events():
            if isinstance(ev, LowBattery):
                emit(
                    "low_battery",
                    f"landmark {ev.landmark_id} battery low: {ev.supply_mv} mV",
                    landmark_id=ev.landmark_id,
                    data={"supply_mv": ev.supply_mv, "days_left": ev.days_left},
                )
            elif isinstance(ev, LandmarkUnreachable):
                emit(
                    "landmark_unreachable",
                    f"landmark {ev.landmark_id} does not answer (radio {ev.address})",
                    landmark_id=ev.landmark_id,
                )
            elif isinstance(ev, LandmarkReachable):
                emit(
                    "landmark_reachable",
                    f"landmark {ev.landmark_id} answers again",
                    landmark_id=ev.landmark_id,
                )
            elif isinstance(ev, TransportStateChanged):
                emit("radio_state", f"radio link {ev.state}", data={"state": ev.state})

    async def _battery_loop(self) -> None:
        interval = self.settings.battery_interval_s
        assert interval is not None
        while True:
            for lm in self.services.map.list():
                if lm.radio is None:
                    continue
                with contextlib.suppress(RfGatewayError, KeyError):
                    await self.services.read_battery(lm.id)
            await asyncio.sleep(interval)

    def on_map_changed(self, landmarks: list[LandmarkPublic]) -> None:
        """Give the new map to every localizer and the new addresses to the gateway."""
        lmap = self.services.map.landmark_map()  # built once per change (20,000: ms)
        for runner in self.services.robots.runners():
            runner.set_map(lmap)
        if self.gateway is not None and self._loop is not None:
            addresses = {lm.id: lm.radio for lm in landmarks if lm.radio}
            self._loop.call_soon_threadsafe(self._update_addresses, addresses)

    def _update_addresses(self, addresses: dict[int, str]) -> None:
        if self.gateway is not None:
            try:
                self.gateway.update_landmarks(addresses)
            except ValueError as exc:
                log.error("gateway refused the new map: %s", exc)

    # -- stop ------------------------------------------------------------------------------
    async def stop(self) -> None:
        """Stop the clock and cameras, leave every LED on, close the radio, end recordings."""
        self._stop.set()
        if self._clock is not None:
            await asyncio.to_thread(self._clock.join, 5.0)
        if self._worker is not None:
            await asyncio.to_thread(self._worker.join, 5.0)
        for cam in self.cameras.values():
            await asyncio.to_thread(cam.stop)
        for wheels in self.wheels.values():
            await asyncio.to_thread(wheels.stop)
        for runner in self.services.robots.runners():
            runner.stop_recording()
        if self.serial is not None:
            await asyncio.to_thread(self.serial.stop)
        for task in self._tasks:
            task.cancel()
        for task in self._tasks:
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await task
        if self.leds is not None:
            await self.leds.stop()
        if self.gateway is not None:
            try:
                await asyncio.wait_for(
                    self.gateway.set_leds(self.gateway.landmarks.keys()), SHUTDOWN_LEDS_TIMEOUT_S
                )
            except (RfGatewayError, TimeoutError) as exc:
                log.warning("could not leave every LED on at shutdown: %s", exc)
            await self.gateway.close()
