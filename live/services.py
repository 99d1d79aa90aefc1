"""`SiteServices`: a running site's in-process services, as a few typed facades.

The REST API, the viewer (through `web.adapter.SiteAdapter`) and the benchmarks use this
object: `map`, `robots`, `leds`, `recordings`, `commissioning` (live/facades.py,
live/commissioning_service.py), the pose and event buses, the keys and the site clock.
`docs/architecture.md` ("Seams") and `docs/server.md` document it.
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import json
import logging
import time
from collections.abc import Coroutine
from typing import TYPE_CHECKING, Any, TypeVar

from sqlalchemy import Engine

from live.alert_service import SiteAlerts
from live.commissioning_service import Commissioning
from live.events import EventHub
from live.facades import LedsAndRadio, Recordings, Robots
from live.floors import SiteFloors
from live.leds.status import EnergyStatus, site_energy
from live.poses import PoseUpdate
from live.runner import SiteRunner
from live.settings import Settings
from live.survey.service import LiveSurvey
from live.upkeep_service import MapUpkeepService
from live.zones_history import HistoryConfig, ZonesAndHistory
from pubsub.bus import Bus
from store import EventLog, KeyStore, MapRepository, RobotStore
from store.db import make_engine, migrate
from store.errors import UnavailableError
from store.floorplan import FloorPlanStore
from store.floorplans import FloorPlans
from store.floors import FloorStore
from store.landmarks import parse_map_json
from store.map_versions import MapVersions
from store.models import LandmarkPublic
from store.zones import PoseHistory, ZoneStore

if TYPE_CHECKING:
    from sim.virtual_site import VirtualSite

log = logging.getLogger(__name__)
T = TypeVar("T")


def prepare_database(engine: Engine) -> str | None:
    """Bring the schema up to date and make sure an admin key exists; returns the new
    admin key when this created it (shown once), else None. Idempotent."""
    migrate(engine)
    return KeyStore(engine).ensure_admin()


class SiteServices:
    """The running site. Build with `SiteServices(settings)`, then `await start()` on the
    server's event loop; `await stop()` at shutdown.

    Attributes:
        settings, engine; map (MapRepository), keys (KeyStore), robot_store (RobotStore),
        log (EventLog); robots (Robots); leds (LedsAndRadio); recordings (Recordings);
        commissioning (Commissioning); survey (LiveSurvey); upkeep (MapUpkeepService, the
        map's proposals from the robots' views); alerts (SiteAlerts, docs/alerts.md); poses
        (Bus[PoseUpdate]); events (EventHub, whose `bus` is a Bus[SiteEvent]); live (the
        SiteRunner, None when stopped or disabled); clock_ns (the site clock);
        initial_admin_key (str once, on first start).
    """

    def __init__(self, settings: Settings, engine: Engine | None = None) -> None:
        self.settings = settings
        self.engine = engine or make_engine(settings.db_url)
        self.initial_admin_key: str | None = prepare_database(self.engine)
        self.map = MapRepository(self.engine)
        self.floors = FloorStore(self.engine)
        self.map_versions = MapVersions(self.engine, self.map, self.floors)
        self.floorplan = FloorPlanStore(settings.data_dir)
        self.floorplans = FloorPlans(settings.data_dir, self.floors, self.floorplan)
        self.keys = KeyStore(self.engine)
        self.robot_store = RobotStore(self.engine)
        self.log = EventLog(self.engine)
        self.events = EventHub(self.log)
        self.poses: Bus[PoseUpdate] = Bus(settings.pose_queue)
        self._t0_ns = time.monotonic_ns()
        self.robots = Robots(self.poses, self.robot_store, self.clock_ns)
        self.site_floors = SiteFloors(
            self.floors, self.map, self.map_versions, self.robots, self.events, self.clock_ns
        )
        self.leds = LedsAndRadio(self.map, self.log)
        max_gb = settings.recordings_max_gb
        self.recordings = Recordings(
            settings.recordings_dir,
            self.robots,
            self.map,
            keep_days=settings.recordings_keep_days,
            max_total_bytes=None if max_gb is None else int(max_gb * 1024**3),
        )
        self.commissioning = Commissioning(self.map, self.robots, self.leds, self.submit)
        self.survey = LiveSurvey(
            self.map, self.robots, self.leds, self.recordings, data_dir=settings.data_dir
        )
        self.upkeep = MapUpkeepService(self.map, self.robots, emit=self.events.emit)
        self.zones = ZoneStore(self.engine)
        self.pose_history = PoseHistory(self.engine)
        self.whereabouts = ZonesAndHistory(
            self.robots,
            self.zones,
            self.pose_history,
            self.events.emit,
            HistoryConfig(keep_days=settings.history_keep_days),
        )
        self.alerts = SiteAlerts(settings, self.robots.runners, self.leds, self.events)
        self.runner: SiteRunner | None = None
        self.loop: asyncio.AbstractEventLoop | None = None
        self.map.add_listener(self._on_map_changed)

    @property
    def virtual_site(self) -> VirtualSite | None:
        """The virtual site, when the live site runs on one."""
        return None if self.runner is None else self.runner.sim

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
        """Import `--map`, start the radio, the robots, the site clock and commissioning."""
        self.loop = asyncio.get_running_loop()
        if self.settings.map_file is not None:
            path = self.settings.map_file
            items = parse_map_json(json.loads(path.read_text(encoding="utf-8")), source=str(path))
            self.map.replace_all(items, actor=f"--map {path}")
        if self.settings.site_enabled:
            self.runner = SiteRunner(
                self.settings,
                map=self.map,
                robot_store=self.robot_store,
                robots=self.robots,
                leds=self.leds,
                events=self.events,
                clock_ns=self.clock_ns,
                floors=self.site_floors,
            )
            await self.runner.start()
        self.commissioning.start()
        self.upkeep.start()
        self.whereabouts.start()
        self.alerts.start()

    async def stop(self) -> None:
        """Stop commissioning and the site (LEDs left all on), then close the database."""
        await self.alerts.stop()
        await self.commissioning.stop()
        await self.upkeep.stop()
        await self.whereabouts.stop()
        self.survey.cancel()
        if self.runner is not None:
            await self.runner.stop()
            self.runner = None
        self.map.remove_listener(self._on_map_changed)
        self.map_versions.close()
        self.keys.close()  # pending last-use writes
        self.events.close()  # events still queued
        self.engine.dispose()

    def _on_map_changed(self, landmarks: list[LandmarkPublic]) -> None:
        self.events.emit(
            "map_changed",
            f"map changed: {len(landmarks)} landmarks",
            data={"count": len(landmarks)},
        )
        if self.runner is not None:
            self.runner.on_map_changed(landmarks)

    def energy(self) -> EnergyStatus:
        """Each landmark's lit state and reason, duty and modelled days left; the site's lit
        fraction and predicted battery life (`live.leds.status`)."""
        return site_energy(self)
