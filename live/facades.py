"""The site's services as a few typed facades, and the Protocols the routes and the viewer
meet them through (docs/architecture.md, "Seams").

`SiteServices` (live/services.py) holds one of each:

- `map`: `store.MapRepository` (landmarks, audit log, undo; listeners on change),
- `robots`: `Robots` (the live robots, their poses, relocalize, configuration),
- `leds`: `LedsAndRadio` (LEDs, radio discovery, batteries),
- `recordings`: `Recordings` (record a robot to a recording folder),
- `commissioning`: `live.commissioning_service.Commissioning` (doubt, identification
  wizard, coverage; the logic is the `commissioning` package).
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np

from live.black_box import BlackBoxRecording, list_black_boxes, read_black_box
from live.leds.coordinator import LedCoordinator
from live.leds.runtime import LedScheduler
from live.poses import PoseUpdate
from live.robots import RobotRunner
from localizer.events import Event, LedsChanged, Mode
from pubsub.bus import Bus, Subscription
from rf_gateway.battery import BatteryMonitorConfig, BatteryReading, days_left
from rf_gateway.errors import RadioTimeout
from rf_gateway.gateway import Gateway
from rf_gateway.transport import DiscoveredRadio, normalize_address
from store import EventLog, MapRepository, RobotStore
from store.errors import ConflictError, NotFoundError, UnavailableError
from store.models import RobotCreate, RobotPublic
from store.recording_catalog import RecordingCatalog, write_meta

log = logging.getLogger(__name__)
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


class Robots:
    """The live robots by name (thread-safe reads), their poses and configuration.

    Args:
        poses: the pose bus every robot publishes on.
        store: the robots' stored configuration.
        clock_ns: the site clock.
    """

    def __init__(self, poses: Bus[PoseUpdate], store: RobotStore, clock_ns: Callable[[], int]):
        self.poses = poses
        self.store = store
        self.clock_ns = clock_ns
        self._runners: dict[str, RobotRunner] = {}
        self._start: Callable[[RobotPublic], object] | None = None
        self._sim_names: frozenset[str] | None = None

    def attach(
        self, start: Callable[[RobotPublic], object] | None, sim_names: Iterable[str] | None
    ) -> None:
        """Called by the live site: how to (re)start a robot, which robots are simulated
        (None: no virtual site). `attach(None, None)` when the site stops."""
        self._start = start
        self._sim_names = None if sim_names is None else frozenset(sim_names)

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

    def deliver(self, robot: str, event: Event) -> None:
        """A sensor event of `robot` to its localizer (the `SensorSink` every `FrameSource`
        feeds); events of a robot that is not running are dropped."""
        runner = self._runners.get(robot)
        if runner is not None:
            runner.handle(event)

    def relocalize(self, name: str, near: tuple[float, float, float] | None = None) -> None:
        """Make a robot identify again, optionally near (x, y, theta) (metres, radians)."""
        self.get(name).relocalize(self.clock_ns(), near)

    def subscribe_poses(
        self, robots: set[str] | None = None, maxsize: int | None = None
    ) -> Subscription[PoseUpdate]:
        """Poses from now on (all robots, or those named), bounded queue (drops counted)."""
        accept = None if not robots else (lambda p: p.robot in robots)
        return self.poses.subscribe(maxsize, accept)

    def apply(self, record: RobotPublic) -> None:
        """(Re)start a robot after its configuration changed (no-op without a live site)."""
        if self._start is None:
            return
        if record.source == "sim" and (
            self._sim_names is None or record.name not in self._sim_names
        ):
            return
        self._start(record)

    def store_camera(self, name: str, sensor: dict[str, Any]) -> RobotPublic:
        """Replace a robot's camera (a `sensor.yaml` mapping, e.g. a new lens calibration)
        and restart it; NotFoundError for an unknown robot, ValueError for a bad camera."""
        record = self.store.get(name)
        data = RobotCreate.model_validate({**record.model_dump(), "camera": sensor})
        stored = self.store.upsert(data)
        self.apply(stored)
        return stored


class LedsAndRadio:
    """The landmarks' LEDs, the radio and the batteries (coroutines: await them on the
    server's loop, or `SiteServices.call` them from a thread).

    Args:
        map: the map (landmark IDs are checked against it).
        log: the battery log.
    """

    def __init__(self, map: MapRepository, log: EventLog) -> None:
        self.map = map
        self.log = log
        self.gateway: Gateway | None = None
        self.coordinator: LedCoordinator | None = None
        self.scheduler: LedScheduler | None = None
        self.discovered: list[DiscoveredRadio] = []

    def attach(
        self,
        gateway: Gateway | None,
        coordinator: LedCoordinator | None,
        scheduler: LedScheduler | None = None,
    ) -> None:
        """Called by the live site once its radio runs (`attach(None, None)` at stop):
        every supply reading of the gateway (its schedule, or `read_battery`) is stored."""
        if self.gateway is not None:
            self.gateway.remove_battery_listener(self._store_reading)
        self.gateway, self.coordinator, self.scheduler = gateway, coordinator, scheduler
        if gateway is not None:
            gateway.add_battery_listener(self._store_reading)

    def keep_lit(
        self, landmark_ids: Iterable[int], reason: str, duration_s: float, *, awake: bool = False
    ) -> None:
        """Keep landmarks lit for `duration_s` whatever the LED schedule needs for the robots
        (thread-safe): what the survey and the wizard measure must be lit to be seen, and
        their requests darken one landmark *of the schedule's lit set*. A pin of the schedule
        (`GET /leds/schedule` shows it as "pinned: <reason>"); nothing to do with every LED
        lit (`all_lit`). `awake`: the caller switches LEDs one at a time and waits for each,
        so sleeping radios keep their wake window open meanwhile (`LedScheduler.pin`)."""
        if self.scheduler is not None:
            self.scheduler.pin(landmark_ids, reason, duration_s, awake=awake)

    def release(self, reason: str) -> None:
        """End the pins given for `reason` (`keep_lit`)."""
        if self.scheduler is not None:
            self.scheduler.unpin_reason(reason)

    def _store_reading(self, reading: BatteryReading) -> None:
        try:
            self.log.add_battery(reading.landmark_id, reading.supply_mv)
        except Exception as exc:  # a failing database loses this reading, stops nothing
            log.warning(
                "battery reading of landmark %d not stored: %s",
                reading.landmark_id,
                str(exc).splitlines()[0][:160],
            )

    def _gw(self) -> Gateway:
        if self.gateway is None:
            raise UnavailableError("no radio: the site runs without a gateway")
        return self.gateway

    @property
    def radio_state(self) -> str:
        """The radio link's state ("absent" without a gateway)."""
        return "absent" if self.gateway is None else str(self.gateway.transport.state)

    @property
    def unreachable(self) -> frozenset[int]:
        """Landmarks whose radio stopped answering."""
        return frozenset() if self.gateway is None else frozenset(self.gateway.unreachable)

    @property
    def controlled(self) -> frozenset[int]:
        """Landmarks the radio switches (what "all lit" means)."""
        return frozenset() if self.gateway is None else frozenset(self.gateway.landmarks)

    async def set_leds(self, lit: frozenset[int] | set[int]) -> LedsChanged:
        """Light exactly `lit`, darken the other landmarks (waits for the radio)."""
        return await self._gw().set_leds(lit)

    async def led(self, landmark_id: int, on: bool) -> LedsChanged:
        self.map.get(landmark_id)
        return await self._gw().led(landmark_id, on)

    async def blink(self, landmark_id: int) -> LedsChanged:
        self.map.get(landmark_id)
        return await self._gw().blink(landmark_id)

    def lit(self) -> frozenset[int]:
        """IDs of the landmarks whose LED is confirmed lit now."""
        gw = self.gateway
        if gw is None or gw.leds is None:
            return frozenset()
        return gw.leds.lit_among(gw.landmarks)

    def add_listener(self, listener: Callable[[LedsChanged], None]) -> bool:
        """Every LED state the gateway publishes, synchronously on the server's loop;
        False (not added) without a gateway."""
        if self.gateway is None:
            return False
        self.gateway.add_led_listener(listener)
        if self.gateway.leds is not None:
            listener(self.gateway.leds)
        return True

    def remove_listener(self, listener: Callable[[LedsChanged], None]) -> None:
        if self.gateway is not None:
            self.gateway.remove_led_listener(listener)

    async def discover(self) -> list[DiscoveredRadio]:
        """Radios that answer and are not in the map (kept in `discovered`)."""
        self.discovered = await self._gw().discover()
        return self.discovered

    async def radio_led(self, address: str, on: bool, *, tries: int = 3) -> None:
        """Switch the LED of a radio that is not a landmark of the map (the identification
        wizard lights a radio from discovery alone to find where it is). Retried on
        timeouts; raises as the transport's `set_pin` (RadioTimeout, RemoteCommandError,
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

    async def read_battery(self, landmark_id: int) -> BatteryReading:
        """Read one landmark's supply now (stored, as every reading is)."""
        self.map.get(landmark_id)
        return await self._gw().battery(landmark_id)

    def battery(self, landmark_id: int) -> BatteryStatus:
        """Latest reading, percent, days left and history from the database."""
        self.map.get(landmark_id)
        replaced = self.log.last_event("cells_replaced", landmark_id=landmark_id)
        # new cells: the old ones' readings say nothing of them (a trend across the swap
        # would read as a charging battery)
        rows = self.log.battery_history(landmark_id, since=None if replaced is None else replaced.t)
        if not rows:
            return BatteryStatus(landmark_id, None, None, None, [])
        cfg = self.gateway.config.battery if self.gateway is not None else BatteryMonitorConfig()
        mv = rows[-1].supply_mv
        span = FULL_SUPPLY_MV - cfg.cutoff_mv
        pct = max(0.0, min(100.0, 100.0 * (mv - cfg.cutoff_mv) / span))
        epoch = rows[0].t
        t_ns = np.array([(r.t - epoch).total_seconds() * 1e9 for r in rows])
        mvs = np.array([r.supply_mv for r in rows], dtype=np.float64)
        left = days_left(t_ns, mvs, cfg.cutoff_mv, min_span_days=cfg.min_fit_span_days)
        hist = [(r.t.isoformat(), r.supply_mv) for r in rows]
        return BatteryStatus(landmark_id, mv, pct, left, hist)


def map_records(map: MapRepository, floor: str) -> list[dict[str, Any]]:
    """The landmarks of `floor` as a recording's `map.json` records (the frame a robot on
    that floor has its poses in)."""
    return [
        lm.model_dump(mode="json", exclude={"created_at", "updated_at", "note", "floor"})
        for lm in map.on_floor(floor)
    ]


class Recordings:
    """Record robots to `<recordings_dir>/<name>-<UTC time>/` (EuRoC-style, docs/recording.md);
    `catalog` lists, zips and deletes them and keeps them within the retention bounds."""

    def __init__(
        self,
        root: Path,
        robots: Robots,
        map: MapRepository,
        *,
        keep_days: float | None = 30.0,
        max_total_bytes: int | None = 20 * 1024**3,
    ) -> None:
        self.root, self.robots, self.map = root, robots, map
        self.catalog = RecordingCatalog(
            root, self._live, keep_days=keep_days, max_total_bytes=max_total_bytes
        )

    def _live(self) -> set[Path]:
        out: set[Path] = set()
        for runner in self.robots.runners():
            rec = runner.recorder
            if rec is not None:
                out.add(Path(rec.root))
        return out

    def start(self, name: str, *, trigger: str = "manual") -> Path:
        """Start recording a robot (`trigger`: why, e.g. "manual", "survey"); the folder."""
        runner = self.robots.get(name)
        now = datetime.now(UTC)
        root = self.root / f"{name}-{now.strftime('%Y%m%dT%H%M%S')}"
        runner.start_recording(root, map_records(self.map, runner.floor))
        write_meta(root, name, trigger, now)
        return root

    def save_black_box(self, name: str) -> BlackBoxRecording:
        """Save a robot's black box now (an operator's request) and return it.

        Raises:
            NotFoundError: no such robot running; ConflictError: it keeps no black box.
        """
        box = self.robots.get(name).black_box
        if box is None:
            raise ConflictError(f"robot {name!r} keeps no black box (black_box_seconds is 0)")
        saved = read_black_box(box.save_now("operator"))
        if saved is None:
            raise ConflictError(f"robot {name!r}: the black box could not be saved (see the log)")
        return saved

    def black_boxes(self, name: str) -> list[BlackBoxRecording]:
        """A robot's saved black boxes, oldest first."""
        return list_black_boxes(self.root, name)

    def stop(self, name: str) -> Path | None:
        """Stop a robot's recording; its folder, or None when it was not recording. The
        oldest recordings beyond the retention bounds go then."""
        path = self.robots.get(name).stop_recording()
        if path is not None:
            self.catalog.prune()
        return path
