"""Where the robots went: their poses kept at a bounded rate (`pose_history`), and zones on
the floor with enter, exit and dwell events.

One `PosePump` feeds both from the pose bus. A robot's pose is kept at most every
`keep_every_s` (1 s: about 86,400 rows a robot a day), and only while it has one (a robot
identifying or lost adds nothing); rows older than `keep_days` are removed hourly. A robot is
inside a zone when it is on the zone's floor (or the zone has none) and its position lies in
the zone's polygon (matplotlib's path test); entering
and leaving are events (`zone_enter`, `zone_exit` with the time spent), and staying longer
than the zone's `dwell_s` one `zone_dwell` per visit. Only poses from landmark fixes and dead
reckoning count: a robot that loses its pose leaves no zone until it has one again.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta
from typing import Any

import numpy as np
from matplotlib.path import Path as PolygonPath

from live.events import EmitEvent
from live.pose_pump import PosePump
from live.poses import PoseUpdate
from store.models import PoseRecord, ZoneRecord
from store.zones import PoseHistory, ZoneStore

log = logging.getLogger(__name__)
TRACKED_MODES = frozenset({"landmark", "dead_reckoning"})


@dataclass(frozen=True)
class HistoryConfig:
    """Attributes: keep_every_s: at most one pose a robot this often, seconds (wall clock);
    keep_days: poses older than this are removed; batch_s: the pose bus is read this often."""

    keep_every_s: float = 1.0
    keep_days: float = 30.0
    batch_s: float = 0.5


@dataclass
class _Visit:
    since_s: float
    dwelt: bool = False


class ZonesAndHistory:
    """Keeps the pose history and raises the zones' events (thread-safe)."""

    def __init__(
        self,
        robots: Any,
        zones: ZoneStore,
        history: PoseHistory,
        emit: EmitEvent,
        config: HistoryConfig | None = None,
    ) -> None:
        self.zones, self.history, self.emit = zones, history, emit
        self.config = config or HistoryConfig()
        self._lock = threading.Lock()
        self._paths: list[tuple[ZoneRecord, PolygonPath]] = []
        self._inside: dict[tuple[str, int], _Visit] = {}
        self._last_kept: dict[str, float] = {}
        self._next_prune = 0.0
        self._pump = PosePump(robots, self.take, batch_s=self.config.batch_s, name="history")

    def start(self) -> None:
        self._on_zones(self.zones.list())
        self.zones.add_listener(self._on_zones)
        self._pump.start()

    async def stop(self) -> None:
        await self._pump.stop()

    def _on_zones(self, zones: list[ZoneRecord]) -> None:
        with self._lock:
            self._paths = [(z, PolygonPath(np.asarray(z.polygon, dtype=float))) for z in zones]
            ids = {z.id for z in zones}
            self._inside = {k: v for k, v in self._inside.items() if k[1] in ids}

    def take(self, batch: Sequence[PoseUpdate]) -> int:
        """Pose updates from the bus: kept at the bounded rate, checked against the zones;
        how many were kept."""
        kept: list[PoseRecord] = []
        for upd in batch:
            if upd.x is None or upd.y is None or upd.theta is None:
                continue
            if upd.mode not in TRACKED_MODES:
                continue
            wall_s = upd.computed_wall_ns * 1e-9
            if wall_s - self._last_kept.get(upd.robot, -np.inf) >= self.config.keep_every_s:
                self._last_kept[upd.robot] = wall_s
                cov = upd.covariance
                sigma = None if cov is None else float(np.sqrt(max(0.0, cov[0, 0] + cov[1, 1])))
                kept.append(
                    PoseRecord(
                        robot=upd.robot,
                        t=datetime.fromtimestamp(wall_s, UTC),
                        t_ns=upd.t_ns,
                        x=upd.x,
                        y=upd.y,
                        theta=upd.theta,
                        sigma_m=sigma,
                        mode=upd.mode,
                        floor=upd.floor,
                    )
                )
            self._zones_at(upd.robot, upd.floor, upd.x, upd.y, wall_s)
        self.history.add(kept)
        now = time.monotonic()
        if now >= self._next_prune:
            self._next_prune = now + 3600.0
            cutoff = datetime.now(UTC) - timedelta(days=self.config.keep_days)
            gone = self.history.prune(cutoff)
            if gone:
                log.info("pose history: %d poses older than %s removed", gone, cutoff)
        return len(kept)

    def _zones_at(self, robot: str, floor: str, x: float, y: float, wall_s: float) -> None:
        with self._lock:
            paths = list(self._paths)
        for zone, path in paths:
            assert zone.id is not None  # stored
            key = (robot, zone.id)
            # a zone of another floor is not where the robot is, whatever its x, y (each
            # floor's map frame has its own origin); a zone of no floor ("") is on every one
            inside = zone.floor in ("", floor) and bool(path.contains_point((x, y)))
            with self._lock:
                visit = self._inside.get(key)
                if inside and visit is None:
                    self._inside[key] = _Visit(wall_s)
                elif not inside and visit is not None:
                    del self._inside[key]
            data = {"zone_id": zone.id, "zone": zone.name, "x": round(x, 3), "y": round(y, 3)}
            if inside and visit is None:
                self.emit(
                    "zone_enter", f"robot {robot} entered zone {zone.name}", robot=robot, data=data
                )
            elif not inside and visit is not None:
                spent = wall_s - visit.since_s
                self.emit(
                    "zone_exit",
                    f"robot {robot} left zone {zone.name} after {spent:.0f} s",
                    robot=robot,
                    data={**data, "spent_s": round(spent, 1)},
                )
            elif (
                inside
                and visit is not None
                and zone.dwell_s is not None
                and not visit.dwelt
                and wall_s - visit.since_s >= zone.dwell_s
            ):
                visit.dwelt = True
                self.emit(
                    "zone_dwell",
                    f"robot {robot} has stayed in zone {zone.name} over {zone.dwell_s:.0f} s",
                    robot=robot,
                    data={**data, "dwell_s": zone.dwell_s},
                )


def coverage_grid(xy: np.ndarray, cell_m: float) -> tuple[tuple[float, float], np.ndarray]:
    """Poses (N, 2) counted on a grid of `cell_m` cells: ((x0, y0) of cell [0, 0]'s corner,
    counts of shape (rows = y cells, cols = x cells))."""
    if cell_m <= 0:
        raise ValueError(f"coverage: cell_m must be positive, got {cell_m}")
    if len(xy) == 0:
        return (0.0, 0.0), np.zeros((0, 0), dtype=np.int64)
    lo = np.floor(xy.min(axis=0) / cell_m) * cell_m
    n = np.floor((xy.max(axis=0) - lo) / cell_m).astype(int) + 1
    idx = np.floor((xy - lo) / cell_m).astype(int)
    counts = np.zeros((n[1], n[0]), dtype=np.int64)
    np.add.at(counts, (idx[:, 1], idx[:, 0]), 1)
    return (float(lo[0]), float(lo[1])), counts


def grid_from_cells(
    cells: Sequence[tuple[int, int, int]], cell_m: float
) -> tuple[tuple[float, float], np.ndarray]:
    """Sparse (column, row, count) cells (`PoseHistory.cell_counts`) as the dense grid of
    `coverage_grid`: ((x0, y0) of cell [0, 0]'s corner, counts (rows, cols))."""
    if not cells:
        return (0.0, 0.0), np.zeros((0, 0), dtype=np.int64)
    a = np.asarray(cells, dtype=np.int64).reshape(-1, 3)
    lo = a[:, :2].min(axis=0)
    n = a[:, :2].max(axis=0) - lo + 1
    counts = np.zeros((n[1], n[0]), dtype=np.int64)
    np.add.at(counts, (a[:, 1] - lo[1], a[:, 0] - lo[0]), a[:, 2])
    return (float(lo[0] * cell_m), float(lo[1] * cell_m)), counts
