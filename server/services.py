"""`SiteServices`: every in-process service of a running site behind one object.

The REST API and the viewer (`web.viewer.Viewer(services)`) use this object and nothing
else: the map repository, the robot registry with latest poses and modes, the pose and event
buses, the gateway and the batteries. `docs/server.md` documents it.
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import logging
import threading
import time
from collections.abc import Coroutine
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any, TypeVar

import numpy as np
from sqlalchemy import Engine

from localizer.events import LedsChanged, Mode
from rf_gateway.battery import BatteryConfig, BatteryReading, days_left
from rf_gateway.errors import RadioTimeout
from rf_gateway.gateway import Gateway
from rf_gateway.transport import DiscoveredRadio, normalize_address
from server.bus import Bus, Subscription
from server.crud import EventLog, KeyStore, MapRepository, RobotStore
from server.db import make_engine, migrate
from server.errors import NotFoundError, UnavailableError
from server.events import EventHub
from server.led_schedule.status import EnergyStatus, site_energy
from server.models import LandmarkPublic, RobotCreate, RobotPublic
from server.poses import PoseUpdate
from server.settings import Settings
from server.site.robot import RobotRunner

log = logging.getLogger(__name__)
T = TypeVar("T")
FULL_SUPPLY_MV = 3200
"""Two fresh AA cells (100 % in `BatteryStatus.percent`)."""


@dataclass(frozen=True)
class BatteryStatus:
    """A landmark's battery as the API and the viewer show it.

    Attributes:
        supply_mv: latest reading, millivolts (None: never read).
        percent: rough charge, 0-100, linear between cut-off and a new cell pair.
        days_left: estimated days until the cut-off voltage (None: unknown).
        history: (UTC ISO time, millivolts), oldest first.
    """

    landmark_id: int
    supply_mv: int | None
    percent: float | None
    days_left: float | None
    history: list[tuple[str, int]]


class RobotRegistry:
    """The live robots by name (thread-safe reads)."""

    def __init__(self) -> None:
        self._runners: dict[str, RobotRunner] = {}

    def add(self, runner: RobotRunner) -> None:
        self._runners = {**self._runners, runner.name: runner}

    def remove(self, name: str) -> RobotRunner | None:
        runners = dict(self._runners)
        out = runners.pop(name, None)
        self._runners = runners
        return out

    def names(self) -> list[str]:
        return sorted(self._runners)

    def runners(self) -> list[RobotRunner]:
        return [self._runners[n] for n in sorted(self._runners)]

    def get(self, name: str) -> RobotRunner:
        try:
            return self._runners[name]
        except KeyError:
            raise NotFoundError(f"robot {name!r} is not running") from None

    def latest(self, name: str) -> PoseUpdate | None:
        return self.get(name).latest

    def mode(self, name: str) -> Mode:
        return self.get(name).mode


class SiteServices:
    """The running site. Build with `SiteServices(settings)`, then `await start()` on the
    server's event loop; `await stop()` at shutdown.

    Attributes (available after `start`):
        settings, engine; map (MapRepository), keys (KeyStore), robot_store (RobotStore),
        log (EventLog); robots (RobotRegistry); poses (Bus[PoseUpdate]); events (EventHub,
        `events.bus` is a Bus[SiteEvent]); gateway (Gateway | None); sim (the `LiveSite` or
        None); clock_ns (the site clock); initial_admin_key (str once, on first start).
    """

    def __init__(self, settings: Settings, engine: Engine | None = None) -> None:
        self.settings = settings
        self.engine = engine or make_engine(settings.db_url)
        migrate(self.engine)
        self.map = MapRepository(self.engine)
        self.keys = KeyStore(self.engine)
        self.robot_store = RobotStore(self.engine)
        self.log = EventLog(self.engine)
        self.events = EventHub(self.log)
        self.robots = RobotRegistry()
        self.poses: Bus[PoseUpdate] = Bus(settings.pose_queue)
        self.gateway: Gateway | None = None
        self.sim: Any = None
        self.site: Any = None  # server.site.builder.LiveSiteRunner
        self.discovered: list[DiscoveredRadio] = []
        self.initial_admin_key: str | None = self.keys.ensure_admin()
        self.loop: asyncio.AbstractEventLoop | None = None
        self._t0_ns = time.monotonic_ns()
        self._map_lock = threading.Lock()
        self.map.add_listener(self._on_map_changed)

    # -- clock and loop --------------------------------------------------------------------
    def clock_ns(self) -> int:
        """The site clock (monotonic, nanoseconds since the services were built)."""
        return time.monotonic_ns() - self._t0_ns

    def submit(self, coro: Coroutine[Any, Any, T]) -> concurrent.futures.Future[T]:
        """Run a coroutine on the server's loop from any other thread (viewer callbacks)."""
        if self.loop is None:
            coro.close()
            raise UnavailableError("the site is not started")
        return asyncio.run_coroutine_threadsafe(coro, self.loop)

    def call(self, coro: Coroutine[Any, Any, T], timeout_s: float = 30.0) -> T:
        """`submit` and wait for the result (from a thread that is not the server's loop)."""
        return self.submit(coro).result(timeout_s)

    # -- lifecycle -------------------------------------------------------------------------
    async def start(self) -> None:
        """Import `--map`, start the radio, the robots and the site clock."""
        from server.site.builder import LiveSiteRunner

        self.loop = asyncio.get_running_loop()
        if self.settings.map_file is not None:
            import json

            from server.crud.landmarks import parse_map_json

            path = self.settings.map_file
            items = parse_map_json(json.loads(path.read_text(encoding="utf-8")), source=str(path))
            self.map.replace_all(items, actor=f"--map {path}")
        if self.settings.site_enabled:
            self.site = LiveSiteRunner(self)
            await self.site.start()

    async def stop(self) -> None:
        """Stop the site (LEDs left all on), then close the database."""
        if self.site is not None:
            await self.site.stop()
            self.site = None
        self.map.remove_listener(self._on_map_changed)
        self.keys.close()  # pending last-use writes
        self.engine.dispose()

    # -- map -------------------------------------------------------------------------------
    def _on_map_changed(self, landmarks: list[LandmarkPublic]) -> None:
        self.events.emit(
            "map_changed",
            f"map changed: {len(landmarks)} landmarks",
            data={"count": len(landmarks)},
        )
        if self.site is not None:
            self.site.on_map_changed(landmarks)

    # -- LEDs and radio (coroutines: await on the server loop, or `call` from a thread) -------
    def _gw(self) -> Gateway:
        if self.gateway is None:
            raise UnavailableError("no radio: the site runs without a gateway")
        return self.gateway

    async def set_leds(self, lit: frozenset[int] | set[int]) -> LedsChanged:
        """Light exactly `lit`, darken the other landmarks (waits for the radio)."""
        return await self._gw().set_leds(lit)

    async def all_leds_on(self) -> LedsChanged:
        return await self._gw().set_leds(self._gw().landmarks.keys())

    async def led(self, landmark_id: int, on: bool) -> LedsChanged:
        self.map.get(landmark_id)
        return await self._gw().led(landmark_id, on)

    async def blink(self, landmark_id: int) -> LedsChanged:
        self.map.get(landmark_id)
        return await self._gw().blink(landmark_id)

    def hold_leds(self, held: bool) -> None:
        """Hold the site's LEDs for a caller that switches them itself (the viewer's
        identification wizard): the robots' own LED requests wait until released
        (thread-safe; nothing to hold without a live site)."""
        coordinator = getattr(self.site, "leds", None)
        if coordinator is not None:
            coordinator.hold(held)

    def lit(self) -> frozenset[int]:
        """IDs of the landmarks whose LED is confirmed lit now."""
        gw = self.gateway
        if gw is None or gw.leds is None:
            return frozenset()
        return gw.leds.lit_among(gw.landmarks)

    async def discover(self) -> list[DiscoveredRadio]:
        """Radios that answer and are not in the map (kept in `discovered`)."""
        self.discovered = await self._gw().discover()
        return self.discovered

    async def radio_led(self, address: str, on: bool, *, tries: int = 3) -> None:
        """Switch the LED of a radio that is not a landmark of the map (the viewer's wizard
        lights a radio from discovery alone to find where it is). Retried on timeouts;
        raises as the transport's `set_pin` (RadioTimeout, RemoteCommandError,
        TransportUnavailable), ValueError for a bad address or a landmark's radio."""
        address = normalize_address(address, source="radio")
        gw = self._gw()
        if address in set(gw.landmarks.values()):
            raise ValueError(f"radio {address} belongs to a landmark: switch it with set_leds")
        for attempt in range(tries):
            try:
                await gw.transport.set_pin(address, on)
                return
            except RadioTimeout:
                if attempt == tries - 1:
                    raise

    # -- batteries ---------------------------------------------------------------------------
    async def read_battery(self, landmark_id: int) -> BatteryReading:
        """Read one landmark's supply now and store it."""
        self.map.get(landmark_id)
        reading = await self._gw().battery(landmark_id)
        self.log.add_battery(landmark_id, reading.supply_mv)
        return reading

    def battery(self, landmark_id: int) -> BatteryStatus:
        """Latest reading, percent, days left and history from the database."""
        self.map.get(landmark_id)
        rows = self.log.battery_history(landmark_id)
        if not rows:
            return BatteryStatus(landmark_id, None, None, None, [])
        cfg = self.gateway.config.battery if self.gateway is not None else BatteryConfig()
        mv = rows[-1].supply_mv
        span = FULL_SUPPLY_MV - cfg.cutoff_mv
        pct = max(0.0, min(100.0, 100.0 * (mv - cfg.cutoff_mv) / span))
        epoch = rows[0].t
        t_ns = np.array([(r.t - epoch).total_seconds() * 1e9 for r in rows])
        mvs = np.array([r.supply_mv for r in rows], dtype=np.float64)
        left = days_left(t_ns, mvs, cfg.cutoff_mv, min_span_days=cfg.min_fit_span_days)
        hist = [(r.t.isoformat(), r.supply_mv) for r in rows]
        return BatteryStatus(landmark_id, mv, pct, left, hist)

    def energy(self) -> EnergyStatus:
        """Each landmark's lit state and reason, duty and modelled days left; the site's lit
        fraction and predicted battery life (`server.led_schedule.status`)."""
        return site_energy(self)

    # -- robots ----------------------------------------------------------------------------
    def relocalize(self, name: str, near: tuple[float, float, float] | None = None) -> None:
        """Make a robot identify again, optionally near (x, y, theta) (metres, radians)."""
        self.robots.get(name).relocalize(self.clock_ns(), near)

    def subscribe_poses(
        self, robots: set[str] | None = None, maxsize: int | None = None
    ) -> Subscription[PoseUpdate]:
        """Poses from now on (all robots, or those named), bounded queue (drops counted)."""
        accept = None if not robots else (lambda p: p.robot in robots)
        return self.poses.subscribe(maxsize, accept)

    def apply_robot(self, record: RobotPublic) -> None:
        """(Re)start a robot after its configuration changed (no-op without a live site)."""
        if self.site is None:
            return
        if record.source == "sim" and (self.sim is None or record.name not in self.sim.robot_names):
            return
        self.site.start_robot(record)

    def store_robot_camera(self, name: str, sensor: dict[str, Any]) -> RobotPublic:
        """Replace a robot's camera (a `sensor.yaml` mapping, e.g. a new lens calibration)
        and restart it; NotFoundError for an unknown robot, ValueError for a bad camera."""
        record = self.robot_store.get(name)
        data = RobotCreate.model_validate({**record.model_dump(), "camera": sensor})
        stored = self.robot_store.upsert(data)
        self.apply_robot(stored)
        return stored

    def start_recording(self, name: str) -> Path:
        """Record a robot to `<data_dir>/recordings/<name>-<UTC time>/`; returns the folder."""
        runner = self.robots.get(name)
        stamp = datetime.now(UTC).strftime("%Y%m%dT%H%M%S")
        root = self.settings.recordings_dir / f"{name}-{stamp}"
        records = [
            lm.model_dump(mode="json", exclude={"created_at", "updated_at", "note"})
            for lm in self.map.list()
        ]
        runner.start_recording(root, records)
        return root

    def stop_recording(self, name: str) -> Path | None:
        """Stop a robot's recording; its folder, or None when it was not recording."""
        return self.robots.get(name).stop_recording()
