"""Robots on floors: which floor's map each robot's localizer holds, moving a robot to
another floor (it left the lift there), and keeping each robot on its floor's current map.

A robot is told it changed floors (`move`: the API, an MQTT command, a VDA 5050
`initPosition` action naming `mapId`); its localizer then takes the new floor's map and
identifies again, near the transition node (the lift's door) when that is given. Nothing
here switches a robot's floor on its own: a robot whose view fits another floor better is
*proposed* that floor (`live.floor_watch`), and a person or the fleet accepts it.
"""

from __future__ import annotations

import logging
from collections.abc import Callable

from live.events import EventHub
from live.facades import Robots
from live.robots import RobotRunner
from localizer.landmark_map import LandmarkMap
from store.floors import FloorStore
from store.landmarks import MapRepository
from store.map_versions import MapVersions
from store.models import FloorCreate

log = logging.getLogger(__name__)
Near = tuple[float, float, float]


class SiteFloors:
    """Floors of the running site as its robots see them.

    Args:
        floors: the site's floors.
        map: the landmark map (every floor's).
        versions: each floor's map versions.
        robots: the live robots.
        events: the site's event hub (`robot_floor_changed`).
        clock_ns: the site clock.
    """

    def __init__(
        self,
        floors: FloorStore,
        map: MapRepository,
        versions: MapVersions,
        robots: Robots,
        events: EventHub,
        clock_ns: Callable[[], int],
    ) -> None:
        self.floors, self.map, self.versions = floors, map, versions
        self.robots, self.events, self.clock_ns = robots, events, clock_ns
        self.start_floor: Callable[[str], str | None] = lambda _name: None
        """Where a robot starts when the site knows (the virtual site's robots); else the
        default floor (`FloorStore.default`)."""
        self._listeners: tuple[Callable[[str, str, str, Near | None], None], ...] = ()

    def add_listener(self, fn: Callable[[str, str, str, Near | None], None]) -> None:
        """Call `fn(robot, floor, old floor, near)` after every move (on the mover's
        thread: it must return at once)."""
        self._listeners = (*self._listeners, fn)

    def remove_listener(self, fn: Callable[[str, str, str, Near | None], None]) -> None:
        self._listeners = tuple(f for f in self._listeners if f is not fn)

    def adopt(self, floors: list[tuple[str, str, int, float]]) -> None:
        """Create the floors (id, name, level, height in metres) the site does not have yet
        (a virtual site's, at its first start)."""
        known = set(self.floors.ids())
        for fid, name, level, height in floors:
            if fid not in known:
                self.floors.create(FloorCreate(id=fid, name=name, level=level, height=height))
        self.versions.sync()

    def map_of(self, floor: str) -> tuple[LandmarkMap, int]:
        """The localizer's map of `floor` and its version."""
        return self.map.landmark_map(floor), self.versions.version(floor)

    def initial(self, robot: str) -> str:
        """The floor a robot starts on."""
        floor = self.start_floor(robot)
        ids = self.floors.ids()
        return floor if floor is not None and floor in ids else self.floors.default()

    def place(self, runner: RobotRunner, floor: str) -> None:
        """Give a new runner its floor and that floor's map (before it gets any event)."""
        lmap, version = self.map_of(floor)
        runner.floor = floor
        runner.set_map(lmap, version)

    def refresh(self) -> None:
        """The map changed: every robot takes the current map of its floor."""
        for runner in self.robots.runners():
            runner.set_map(*self.map_of(runner.floor))

    def move(
        self, name: str, floor: str, near: Near | None = None, *, by: str = "api"
    ) -> RobotRunner:
        """Robot `name` is now on `floor` (near (x, y, theta) on it, metres and radians):
        it takes that floor's map and identifies again. Emits `robot_floor_changed`.

        Raises:
            NotFoundError: an unknown robot, or `UnknownFloorError` (a NotFoundError) naming
                a floor the site does not have; nothing changes then.
        """
        runner = self.robots.get(name)
        self.floors.check(floor, what=f"robot {name!r}")
        old = runner.floor
        lmap, version = self.map_of(floor)
        runner.set_floor(floor, lmap, version, self.clock_ns(), near)
        self.events.emit(
            "robot_floor_changed",
            f"robot {name} is on floor {floor} (was {old}; {by})",
            robot=name,
            data={
                "floor": floor,
                "from": old,
                "by": by,
                "near": None if near is None else list(near),
            },
        )
        log.info("robot %s: floor %s -> %s (%s)", name, old, floor, by, extra={"robot": name})
        for fn in self._listeners:
            try:
                fn(name, floor, old, near)
            except Exception:
                log.exception("robot %s: a floor listener failed", name)
        return runner
