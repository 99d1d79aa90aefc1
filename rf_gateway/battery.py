"""Battery monitoring: reading history and the days-left estimate from the discharge trend.

A landmark runs its XBee 3 straight from two AA cells (no regulator, or `%V` would only see
the regulated voltage): about 3.2 V new, and XBee 3's minimum supply, 2.1 V, is the cut-off.
The estimate fits a straight line to voltage against time over the recent history and
extrapolates it to the cut-off. Alkaline cells discharge non-linearly (flat, then a knee),
so the estimate is optimistic early on and becomes reliable in the last weeks.
"""

from __future__ import annotations

import asyncio
from collections import deque
from collections.abc import Awaitable, Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from lighting.battery import BatteryConfig

NS_PER_DAY = 86_400 * 10**9


@dataclass(frozen=True)
class BatteryMonitorConfig:
    """Battery monitoring settings (the cells themselves: `lighting.battery.BatteryConfig`).

    Attributes:
        interval_s: time between scheduled reads of every landmark; None: no schedule.
        low_mv: a reading at or below this raises a LowBattery event, millivolts.
        low_hysteresis_mv: a low landmark must read this much above `low_mv` to clear.
        cells: the landmark's cells and loads; their brown-out voltage is the cut-off
            (`cutoff_mv`) the days-left estimate extrapolates to.
        history_len: readings kept per landmark.
        fit_window_days: only readings this recent enter the trend fit.
        min_fit_span_days: no estimate before the history spans this long.
        first_read_s: the first scheduled read starts this long after the start-up sweep
            has lit every LED, seconds (with sleeping radios each read holds one of the
            coordinator's few in-flight slots up to a sleep period: not while robots
            identify after a start).
    """

    interval_s: float | None = 3600.0
    low_mv: int = 2400
    low_hysteresis_mv: int = 50
    cells: BatteryConfig = field(default_factory=BatteryConfig)
    history_len: int = 2000
    fit_window_days: float = 30.0
    min_fit_span_days: float = 0.5
    first_read_s: float = 0.0

    @property
    def cutoff_mv(self) -> int:
        """The supply at which the landmark stops working, millivolts (XBee 3: 2100)."""
        return round(self.cells.brownout_v * 1000.0)


@dataclass(frozen=True)
class BatteryReading:
    """One supply reading.

    Attributes:
        landmark_id: the landmark.
        t_ns: when it was read (gateway clock), nanoseconds.
        supply_mv: supply voltage, millivolts.
        days_left: estimated days until `cutoff_mv`, None when the trend is unknown or flat.
    """

    landmark_id: int
    t_ns: int
    supply_mv: int
    days_left: float | None = None

    @property
    def volts(self) -> float:
        return self.supply_mv / 1000.0


def days_left(
    t_ns: np.ndarray, supply_mv: np.ndarray, cutoff_mv: float, *, min_span_days: float = 0.5
) -> float | None:
    """Days from the last reading until the fitted discharge line reaches `cutoff_mv`.

    Fits supply_mv = a + b * t by least squares.

    Args:
        t_ns: reading times, shape (N,), nanoseconds.
        supply_mv: readings, shape (N,), millivolts.
        cutoff_mv: cut-off supply, millivolts.
        min_span_days: shorter histories give None.

    Returns:
        Days left (0 when the fit is already below the cut-off), or None when there are
        fewer than 3 readings, the span is too short, or the voltage is not falling.
    """
    t = np.asarray(t_ns, dtype=np.float64).reshape(-1)
    v = np.asarray(supply_mv, dtype=np.float64).reshape(-1)
    if len(t) != len(v):
        raise ValueError(f"days_left: {len(t)} times but {len(v)} readings")
    if len(t) < 3:
        return None
    t_days = (t - t[-1]) / NS_PER_DAY
    if t_days.max() - t_days.min() < min_span_days:
        return None
    slope, intercept = np.polyfit(t_days, v, 1)  # mV/day, mV at the last reading
    if slope >= 0.0:
        return None
    return max(0.0, float((cutoff_mv - intercept) / slope))


class BatteryHistory:
    """Readings per landmark, bounded, and the estimate from them."""

    def __init__(self, config: BatteryMonitorConfig) -> None:
        self.config = config
        self._readings: dict[int, deque[tuple[int, int]]] = {}
        self._low: set[int] = set()

    def add(self, landmark_id: int, t_ns: int, supply_mv: int) -> BatteryReading:
        """Record a reading; returns it with the current days-left estimate."""
        history = self._readings.setdefault(landmark_id, deque(maxlen=self.config.history_len))
        history.append((t_ns, supply_mv))
        return BatteryReading(landmark_id, t_ns, supply_mv, self.estimate_days_left(landmark_id))

    def readings(self, landmark_id: int) -> list[tuple[int, int]]:
        """(t_ns, supply_mv) pairs of one landmark, oldest first."""
        return list(self._readings.get(landmark_id, ()))

    def latest(self, landmark_id: int) -> BatteryReading | None:
        history = self._readings.get(landmark_id)
        if not history:
            return None
        t_ns, mv = history[-1]
        return BatteryReading(landmark_id, t_ns, mv, self.estimate_days_left(landmark_id))

    def estimate_days_left(self, landmark_id: int) -> float | None:
        history = self._readings.get(landmark_id)
        if not history:
            return None
        window_ns = self.config.fit_window_days * NS_PER_DAY
        recent = [(t, v) for t, v in history if history[-1][0] - t <= window_ns]
        arr = np.asarray(recent, dtype=np.float64)
        return days_left(
            arr[:, 0], arr[:, 1], self.config.cutoff_mv, min_span_days=self.config.min_fit_span_days
        )

    @property
    def low(self) -> frozenset[int]:
        """Landmarks whose battery is low now (read at or below `low_mv`, not yet
        `low_hysteresis_mv` above it again)."""
        return frozenset(self._low)

    def became_low(self, reading: BatteryReading) -> bool:
        """True the first time a landmark reads at or below `low_mv` (until it recovers
        `low_hysteresis_mv` above it: new cells)."""
        lid, mv = reading.landmark_id, reading.supply_mv
        if mv <= self.config.low_mv and lid not in self._low:
            self._low.add(lid)
            return True
        if mv > self.config.low_mv + self.config.low_hysteresis_mv:
            self._low.discard(lid)
        return False

    def forget(self, landmark_id: int) -> None:
        self._readings.pop(landmark_id, None)
        self._low.discard(landmark_id)


async def read_all(
    read: Callable[[int], Awaitable[BatteryReading]], ids: Sequence[int], batch: int
) -> list[BatteryReading]:
    """Read every landmark, `batch` at a time; failures are skipped (their callers raise
    the events)."""
    readings: list[BatteryReading] = []
    for start in range(0, len(ids), batch):
        chunk = ids[start : start + batch]
        results = await asyncio.gather(*(read(lid) for lid in chunk), return_exceptions=True)
        readings += [r for r in results if isinstance(r, BatteryReading)]
    return readings
