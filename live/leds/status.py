"""What staff see of the landmarks' energy: per landmark whether it is lit and why, its duty
cycle under the schedule, the days its cells have left at that duty (the energy model, from
the measured voltage), and a flag raised before its LED dims; for the site, the lit
fraction and the predicted battery life (median and worst landmark) for `/metrics`.
"""

from __future__ import annotations

import functools
import statistics
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from typing import TYPE_CHECKING

from prometheus_client.core import GaugeMetricFamily, Metric

from lighting.battery import BatteryConfig
from lighting.energy import DutyCycle, RadioSleep, charge_from_voltage, predict_life_days
from live.leds.runtime import LedScheduler

if TYPE_CHECKING:
    from live.services import SiteServices

DIM_BRIGHTNESS = 0.6
"""Below this share of its fresh brightness a landmark's LED counts as dim (fainter spots
fall under the detection threshold at the edge of the view)."""
WARN_DAYS = 7.0
"""A landmark is flagged this many days (at the current schedule) before its LED dims."""
MIN_DUTY_S = 3600.0
"""The duty measured over less than this (a fresh start: every LED lit while the robots
identify) does not flag a landmark; only its voltage near the dimming point does, s."""
NEAR_DIM_MV = 150
"""Within this much of the dimming voltage a landmark is flagged whatever the duty, mV."""


def dim_supply_v(battery: BatteryConfig | None = None) -> float:
    """Supply voltage at which the LED's current (its brightness) falls to
    `DIM_BRIGHTNESS` of a fresh pair's, volts."""
    cfg = battery or BatteryConfig()
    fresh_v = cfg.nominal_led_current_ma * cfg.led_resistor_ohm / 1000.0 + cfg.led_forward_v
    return cfg.led_forward_v + DIM_BRIGHTNESS * (fresh_v - cfg.led_forward_v)


@functools.lru_cache(maxsize=4096)
def _days(
    duty: float, messages_per_s: float, charge: float, period_s: float | None, *, dim: bool
) -> float:
    """`predict_life_days` memoised on rounded inputs (the viewer asks at a few hertz)."""
    battery = BatteryConfig(brownout_v=dim_supply_v()) if dim else None
    sleep = None if period_s is None else RadioSleep(period_s)
    return predict_life_days(
        DutyCycle(duty, messages_per_s), battery=battery, charge=charge, sleep=sleep
    )


@dataclass(frozen=True)
class LandmarkEnergy:
    """One landmark's energy as shown.

    Attributes:
        lit: lit now (confirmed).
        reason: why the schedule lights it (None: dark, or no schedule).
        duty: share of the time lit since the site started (1.0 when all lit).
        days_left: days until its radio browns out at that duty, from the measured voltage
            (None: never read).
        days_to_dim: days until its LED dims at that duty (None: never read).
        low: flagged (dims within `WARN_DAYS` at the duty so far, once that duty has been
            measured for `MIN_DUTY_S`, or its voltage is within `NEAR_DIM_MV` of dimming).
    """

    landmark_id: int
    lit: bool
    reason: str | None
    duty: float
    days_left: float | None
    days_to_dim: float | None
    low: bool


class EnergyStatus:
    """Reads the schedule's books and the battery readings.

    Args:
        scheduler: the LED scheduler (None: `all_lit`, every LED on all the time).
        lit_now: the landmarks lit now.
        supply_mv: landmark ID -> latest measured supply, mV (None: never read).
        sleep_period_s: the radios' sleep period (None: awake).
        commands: radio commands sent so far (the gateway's count), for each landmark's
            share of messages (each wakes its radio, `lighting.energy`).
        landmarks: the number of landmarks the gateway controls.
    """

    def __init__(
        self,
        scheduler: LedScheduler | None,
        lit_now: Callable[[], frozenset[int]],
        supply_mv: Callable[[int], int | None],
        sleep_period_s: float | None,
        *,
        commands: Callable[[], int] = lambda: 0,
        landmarks: Callable[[], int] = lambda: 1,
    ) -> None:
        self.scheduler = scheduler
        self._lit_now = lit_now
        self._supply_mv = supply_mv
        self._commands = commands
        self._landmarks = landmarks
        self.sleep = None if sleep_period_s is None else RadioSleep(sleep_period_s)

    def duty(self, landmark_id: int) -> float:
        return 1.0 if self.scheduler is None else self.scheduler.duty(landmark_id)

    def messages_per_s(self) -> float:
        """Radio commands per landmark per second so far (the site's, shared evenly)."""
        s = self.scheduler
        if s is None or s.accounted_s <= 0:
            return 0.0
        return self._commands() / max(self._landmarks(), 1) / s.accounted_s

    def landmark(self, landmark_id: int) -> LandmarkEnergy:
        lit = landmark_id in self._lit_now()
        reason = None if self.scheduler is None else self.scheduler.reason(landmark_id)
        duty = DutyCycle(self.duty(landmark_id), self.messages_per_s())
        mv = self._supply_mv(landmark_id)
        left = to_dim = None
        if mv is not None:
            charge = round(charge_from_voltage(mv), 3)
            period = None if self.sleep is None else self.sleep.period_s
            d, m = round(duty.led_duty, 3), round(duty.messages_per_s, 4)
            left = _days(d, m, charge, period, dim=False)
            to_dim = _days(d, m, charge, period, dim=True)
        settled = self.scheduler is None or self.scheduler.accounted_s >= MIN_DUTY_S
        near_dim = mv is not None and mv <= dim_supply_v() * 1000.0 + NEAR_DIM_MV
        low = to_dim is not None and to_dim < WARN_DAYS and (settled or near_dim)
        return LandmarkEnergy(landmark_id, lit, reason, duty.led_duty, left, to_dim, low)

    def lit_fraction(self) -> float:
        """Time-averaged share of the landmarks lit (1.0 without a schedule)."""
        return 1.0 if self.scheduler is None else self.scheduler.lit_fraction

    def site_life_days(self, landmark_ids: Iterable[int]) -> tuple[float, float] | None:
        """(median, worst) days a fresh pair of cells lasts at each landmark's duty so far."""
        days = [
            predict_life_days(DutyCycle(self.duty(i), self.messages_per_s()), sleep=self.sleep)
            for i in landmark_ids
        ]
        if not days:
            return None
        return statistics.median(days), min(days)


def site_energy(
    services: SiteServices, supply_mv: Callable[[int], int | None] | None = None
) -> EnergyStatus:
    """The energy status of a running site (its scheduler, gateway and battery log;
    `supply_mv` replaces the battery log's latest reading, e.g. by a cached one)."""
    live = services.runner
    gw = services.leds.gateway

    def supply(landmark_id: int) -> int | None:
        return services.leds.battery(landmark_id).supply_mv

    return EnergyStatus(
        None if live is None else live.scheduler,
        services.leds.lit,
        supply if supply_mv is None else supply_mv,
        services.settings.radio_sleep_period_s,
        commands=lambda: 0 if gw is None else gw.stats.commands,
        landmarks=lambda: 0 if gw is None else len(gw.landmarks),
    )


def energy_metrics(services: SiteServices) -> Iterator[Metric]:
    """`/metrics`: lit landmarks now, the time-averaged lit fraction, and the predicted
    battery life of the site (median and worst landmark, fresh cells, at the duty so far)."""
    gw = services.leds.gateway
    if gw is None:
        return
    status = site_energy(services)
    yield GaugeMetricFamily("irloc_leds_lit", "landmarks lit now", value=len(services.leds.lit()))
    yield GaugeMetricFamily(
        "irloc_leds_lit_fraction",
        "share of the landmarks lit, averaged over time since the site started",
        value=status.lit_fraction(),
    )
    life = status.site_life_days(gw.landmarks)
    if life is not None:
        days = GaugeMetricFamily(
            "irloc_battery_life_days",
            "predicted life of fresh cells at the landmarks' duty so far (energy model)",
            labels=["landmark"],
        )
        days.add_metric(["median"], life[0])
        days.add_metric(["worst"], life[1])
        yield days
