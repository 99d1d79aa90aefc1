"""The live site: builds the virtual site (if any), the radio gateway, the LED coordinator,
one `RobotRunner` per robot and the `FrameSource`s that feed them.

Threads: each source has its own (the virtual site's clock and feeder, a server camera, a
serial wheel port); a remote robot's events are fed on worker threads from its WebSocket.
All deliver through one sink, `Robots.deliver`. The gateway, the LED coordinator and the
battery poll run on the server's event loop. It is handed the facades it works on
(live/facades.py) and writes nothing back into `SiteServices`.
"""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
import logging
from collections.abc import Callable, Iterable
from functools import partial
from pathlib import Path
from typing import Protocol

from live.black_box import BlackBox, BlackBoxConfig, BlackBoxRecording
from live.events import EventHub
from live.facades import map_records
from live.floor_watch import FloorWatch
from live.floors import SiteFloors
from live.leds import LedScheduler
from live.leds.coordinator import LedCoordinator
from live.leds.wiring import (
    attach_scheduler,
    gateway_config,
    localizer_config,
    radio_sleep,
    xbee_config,
)
from live.pose_reasons import ReasonTally, mode_change_event
from live.poses import PoseUpdate
from live.recording_queue import MIB, RecordingLimits
from live.robots import RobotRunner, make_localizer
from live.serial_sink import SerialSink
from live.settings import Settings
from live.supervisor import SiteSupervisor
from localizer.camera import camera_from_sensor, sensor_from_camera
from localizer.events import Event, LedRequest, Mode
from localizer.robot import RobotGeometry
from pubsub.bus import Bus, Subscription
from rf_gateway.errors import RfGatewayError
from rf_gateway.events import (
    LandmarkReachable,
    LandmarkUnreachable,
    LowBattery,
    TransportStateChanged,
)
from rf_gateway.gateway import Gateway
from sensors.camera import CameraSource
from sensors.remote import RemoteSource
from sensors.serial_wheels import SerialWheelSource
from sensors.sim_source import SimSource
from sensors.sources import FrameSource
from sim.robot import FloorArrival
from sim.virtual_site import VirtualSite
from store import MapRepository, RobotStore
from store.landmarks import parse_map_json
from store.models import LandmarkPublic, RobotCreate, RobotPublic

log = logging.getLogger(__name__)
SITE_STEP_HZ = 100.0
MAX_FRAME_LAG_S = 0.25
SHUTDOWN_LEDS_TIMEOUT_S = 5.0


class RobotHost(Protocol):
    """What the live site needs of the robot registry (`live.facades.Robots`)."""

    poses: Bus[PoseUpdate]

    def add(self, runner: RobotRunner) -> None: ...
    def remove(self, name: str) -> RobotRunner | None: ...
    def runners(self) -> list[RobotRunner]: ...
    def deliver(self, robot: str, event: Event) -> None: ...
    def subscribe_poses(
        self, robots: set[str] | None = None, maxsize: int | None = None
    ) -> Subscription[PoseUpdate]: ...
    def attach(
        self, start: Callable[[RobotPublic], object] | None, sim_names: Iterable[str] | None
    ) -> None: ...


class LedHost(Protocol):
    """What the live site needs of the LED facade (`live.facades.LedsAndRadio`)."""

    def attach(
        self,
        gateway: Gateway | None,
        coordinator: LedCoordinator | None,
        scheduler: LedScheduler | None = None,
    ) -> None: ...


class SiteRunner:
    """Start and stop everything live.

    Args:
        settings: the server's settings.
        map, robot_store: the data layer.
        robots: the live robots (the runner adds and removes them; `Robots.deliver` is the
            sink of every source).
        leds: the LED facade (the runner attaches its gateway, LED coordinator and schedule).
        events: the site's event hub.
        clock_ns: the site clock.
    """

    def __init__(
        self,
        settings: Settings,
        *,
        map: MapRepository,
        robot_store: RobotStore,
        robots: RobotHost,
        leds: LedHost,
        events: EventHub,
        clock_ns: Callable[[], int],
        floors: SiteFloors | None = None,
    ) -> None:
        self.settings = settings
        self.floors = floors
        self.map, self.robot_store, self.robots = map, robot_store, robots
        self.led_facade, self.events, self.clock_ns = leds, events, clock_ns
        self.sim: VirtualSite | None = None
        self.sim_source: SimSource | None = None
        self.gateway: Gateway | None = None
        self.leds: LedCoordinator | None = None
        self.scheduler: LedScheduler | None = None
        self.cameras: dict[str, CameraSource] = {}
        self.wheels: dict[str, SerialWheelSource] = {}
        self.remotes: dict[str, RemoteSource] = {}
        self.serial: SerialSink | None = None
        self.floor_watch: FloorWatch | None = None
        """Proposes the floor a robot without a fix seems to be on (`live.floor_watch`)."""
        self._tasks: list[asyncio.Task[None]] = []
        self._loop: asyncio.AbstractEventLoop | None = None
        self.supervisor = SiteSupervisor(lambda: self.sources, self.robots.runners, events)

    @property
    def sources(self) -> list[FrameSource]:
        """Every running source."""
        out: list[FrameSource] = [] if self.sim_source is None else [self.sim_source]
        return [*out, *self.cameras.values(), *self.wheels.values(), *self.remotes.values()]

    @property
    def frames_skipped(self) -> int:
        """Virtual-site frames skipped for being late."""
        return 0 if self.sim_source is None else self.sim_source.frames_skipped

    # -- start -----------------------------------------------------------------------------
    async def start(self) -> None:
        self._loop = asyncio.get_running_loop()
        if self.settings.radio == "sim":
            self.sim = self._build_sim()
            self._adopt_sim(self.sim)
        await self._start_gateway()
        self.robots.attach(self.start_robot, None if self.sim is None else self.sim.robot_names)
        for robot in self.robot_store.list():
            if robot.source == "sim" and robot.name not in self._sim_names():
                continue
            self.start_robot(robot)
        if self.settings.serial_sink:
            robots = {self.settings.serial_robot} if self.settings.serial_robot else None
            sub = self.robots.subscribe_poses(robots)
            self.serial = SerialSink.open(sub, self.settings.serial_sink, self.settings.serial_baud)
            self.serial.start()
        if self.sim is not None:
            self.sim_source = SimSource(
                self.sim, self.clock_ns, step_hz=SITE_STEP_HZ, max_frame_lag_s=MAX_FRAME_LAG_S
            )
            self.sim_source.on_floor = self._on_floor_arrival
            self.sim_source.start(self.robots.deliver)
        self._tasks.append(asyncio.get_running_loop().create_task(self.supervisor.run()))

    def start_robot(self, robot: RobotPublic) -> RobotRunner:
        """Run (or restart with a new configuration) one robot's localizer and sources."""
        self.stop_robot(robot.name)
        geometry = RobotGeometry(robot.wheel_base, robot.max_speed)
        camera = camera_from_sensor(robot.camera, source=f"robot {robot.name} camera")
        runner = RobotRunner(
            robot.name,
            camera,
            geometry,
            make_localizer(
                camera, self.map.landmark_map(), geometry, localizer_config(self.settings)
            ),
            publish=self.robots.poses.publish,
            request_leds=self._request_leds,
            source=robot.source,
        )
        runner.on_mode_change = partial(self._on_mode_change, runner.reasons)
        if self.floors is not None:
            self.floors.place(runner, self.floors.initial(robot.name))
        runner.on_recording_stopped = self._on_recording_stopped
        runner.recording_limits = RecordingLimits(
            max_bytes=self.settings.recording_max_mb * MIB,
            max_s=self.settings.recording_max_s,
            min_free_bytes=self.settings.recording_min_free_mb * MIB,
        )
        runner.black_box = self._black_box(runner)
        self.robots.add(runner)
        if robot.source == "camera" and robot.device:
            cam = CameraSource(robot.name, robot.device, self.clock_ns)
            cam.start(self.robots.deliver)
            self.cameras[robot.name] = cam
        if robot.source == "camera" and robot.wheel_port:
            wheels = SerialWheelSource(
                robot.name, robot.wheel_port, robot.wheel_baud, self.clock_ns
            )
            wheels.start(self.robots.deliver)
            self.wheels[robot.name] = wheels
        if robot.source == "remote":
            remote = RemoteSource(robot.name)
            remote.start(self.robots.deliver)
            self.remotes[robot.name] = remote
        return runner

    def remote(self, name: str) -> RemoteSource | None:
        """The source of a running remote robot (its WebSocket pushes into it)."""
        return self.remotes.get(name)

    def stop_robot(self, name: str) -> None:
        """Stop a robot's own sources (if any) and remove it from the registry."""
        for sources in (self.cameras, self.wheels, self.remotes):
            src = sources.pop(name, None)
            if src is not None:
                src.stop()
        runner = self.robots.remove(name)
        if runner is not None:
            runner.stop_recording()
            if runner.black_box is not None:
                runner.black_box.close()

    def _black_box(self, runner: RobotRunner) -> BlackBox | None:
        """A robot's black box (`live.black_box`; None when `black_box_seconds` is 0); its
        recordings hold the map of the floor the robot is on at the save."""
        s = self.settings
        if s.black_box_seconds <= 0:
            return None
        config = BlackBoxConfig(
            seconds=s.black_box_seconds,
            quality_below=s.black_box_quality_below,
            max_bytes=int(s.black_box_max_mb * 1e6),
        )
        box = BlackBox(
            runner.name,
            runner.camera,
            runner.geometry,
            lambda: map_records(self.map, runner.floor),
            s.recordings_dir,
            config,
        )
        box.on_saved = self._on_black_box
        return box

    def _on_black_box(self, saved: BlackBoxRecording) -> None:
        reason = f" ({saved.reason})" if saved.reason else ""
        self.events.emit(
            "black_box_saved",
            f"robot {saved.robot}: black box saved on {saved.trigger}{reason}",
            robot=saved.robot,
            data={"trigger": saved.trigger, "reason": saved.reason, "path": str(saved.path)},
        )

    def _build_sim(self) -> VirtualSite:
        from sim.scenario import load_scenario

        scenario = load_scenario(self.settings.scenario)
        if not self.settings.sim_robots:  # the same world; its robots run as agents
            scenario = dataclasses.replace(scenario, robots=())
        return VirtualSite(
            scenario,
            seed=self.settings.seed,
            clock_ns=self.clock_ns,
            radio_sleep=radio_sleep(self.settings),
        )

    def _on_floor_arrival(self, robot: str, arrival: FloorArrival) -> None:
        """A virtual robot left the lift: its fleet manager tells the site (when the route
        says it does) that it is on that floor at the lift's node."""
        if arrival.announce and self.floors is not None:
            try:
                self.floors.move(robot, arrival.floor, arrival.pose, by="fleet (lift)")
            except KeyError as exc:
                log.error("robot %s left the lift: %s", robot, exc)

    def _sim_names(self) -> list[str]:
        return list(self.sim.robot_names) if self.sim is not None else []

    def _adopt_sim(self, sim: VirtualSite) -> None:
        """First start on a virtual site: take its floors, its surveyed map and its robots."""
        if self.floors is not None:
            self.floors.adopt([(f.id, f.name, f.level, f.height_m) for f in sim.floors])
            self.floors.start_floor = lambda name: (
                sim.true_floor(name) if name in sim.robot_names else None
            )
        if not self.map.list():
            items = parse_map_json({"landmarks": sim.landmark_records()}, source="virtual site")
            self.map.replace_all(items, actor="virtual site")
        known = {r.name for r in self.robot_store.list()}
        for name in sim.robot_names:
            if name in known:
                continue
            geo = sim.robot_geometry(name)
            self.robot_store.upsert(
                RobotCreate(
                    name=name,
                    source="sim",
                    wheel_base=geo.wheel_base,
                    max_speed=geo.max_speed,
                    camera=sensor_from_camera(sim.camera(name)),
                )
            )

    async def _start_gateway(self) -> None:
        from rf_gateway.factory import make_transport

        try:
            transport = make_transport(
                self.settings.radio,
                sim_radio=None if self.sim is None else self.sim.radio,
                xbee_config=xbee_config(self.settings),
            )
        except ValueError as exc:
            log.error("no radio: %s", exc)
            return
        # the gateway's own schedule reads every landmark's supply; the LED facade stores it
        config = gateway_config(self.settings)
        self.gateway = Gateway(transport, self.map.addresses(), config, clock_ns=self.clock_ns)
        await self.gateway.start()
        self.leds = LedCoordinator(self.gateway, self.robots.runners, self._on_led_error)
        self.leds.start()
        if self.settings.led_policy == "scheduled":
            self.scheduler = attach_scheduler(
                self.map,
                self.robots.runners,
                self.leds,
                self.clock_ns,
                self.settings,
                routes=self._routes,
            )
        self.led_facade.attach(self.gateway, self.leds, self.scheduler)
        if self.floors is not None:
            self.floor_watch = FloorWatch(
                self.floors,
                self.events,
                self._request_leds,
                self.clock_ns,
                localizer_config(self.settings),
            )
            self.floor_watch.start()
        loop = asyncio.get_running_loop()
        self._tasks.append(loop.create_task(self._gateway_events()))

    def _routes(self, robot: str) -> tuple[tuple[float, float], ...]:
        """Where a robot drives next, as far as the site knows (the virtual site's routes;
        robots of a real fleet: none yet)."""
        sim = self.sim
        if sim is None or robot not in sim.robot_names:
            return ()
        return sim.planned_route(robot)

    # -- running ---------------------------------------------------------------------------
    def _request_leds(self, robot: str, req: LedRequest) -> None:
        if self.floor_watch is not None and self.floor_watch.trying(robot):
            return  # its view is tried on other floors: their probes go first
        if self.leds is not None:
            self.leds.request(robot, req)

    def _on_led_error(self, robot: str, message: str) -> None:
        self.events.emit("led_request_failed", f"robot {robot}: {message}", robot=robot)

    def _on_recording_stopped(self, robot: str, root: Path, reason: str) -> None:
        self.events.emit(
            "recording_stopped",
            f"robot {robot}: recording stopped: {reason} ({root.name} keeps what was written)",
            robot=robot,
            data={"folder": root.name, "reason": reason},
        )

    def _on_mode_change(self, reasons: ReasonTally, robot: str, old: Mode, new: Mode) -> None:
        event = mode_change_event(robot, old, new, reasons)
        if event is not None:
            kind, message, data = event
            self.events.emit(kind, message, robot=robot, data=data or None)

    async def _gateway_events(self) -> None:
        assert self.gateway is not None
        emit = self.events.emit
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

    def on_map_changed(self, landmarks: list[LandmarkPublic]) -> None:
        """Give the new map to every localizer and the new addresses to the gateway."""
        if self.floors is not None:  # each robot its floor's map
            self.floors.refresh()
        else:
            lmap = self.map.landmark_map()  # built once per change (20,000: ms)
            for runner in self.robots.runners():
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
        self.robots.attach(None, None)
        if self.floor_watch is not None:
            await asyncio.to_thread(self.floor_watch.stop)
        for source in self.sources:
            await asyncio.to_thread(source.stop)
        for runner in self.robots.runners():
            runner.stop_recording()
        if self.serial is not None:
            await asyncio.to_thread(self.serial.stop)
        for task in self._tasks:
            task.cancel()
        for task in self._tasks:
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await task
        self.led_facade.attach(None, None)
        if self.scheduler is not None:
            await self.scheduler.stop()
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
