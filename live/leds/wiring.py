"""Wiring of the LED schedule into a running site (`live.runner` calls these)."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterable, Mapping
from typing import TYPE_CHECKING, Any

import numpy as np

from lighting.policy import ScheduleConfig
from lighting.wake_window import WakeWindow, WakeWindowConfig
from live.leds.runtime import LedScheduler
from live.settings import Settings
from localizer.config import LocalizerConfig
from rf_gateway.battery import BatteryMonitorConfig
from rf_gateway.config import GatewayConfig, SleepConfig
from rf_gateway.scheduler import Priority

if TYPE_CHECKING:
    from live.leds.coordinator import LedCoordinator
    from live.robots import RobotRunner
    from store import MapRepository

AIR_LATENCY_S = 0.05
"""A command's time on the air to an awake radio and back (docs/rf_gateway.md), seconds."""


FIRST_BATTERY_READ_S = 30.0
"""With sleeping radios the first battery reads wait this long after the start-up sweep
(robots identify meanwhile, and every read holds a radio slot up to a sleep period), s."""


def wake_latency_s(settings: Settings) -> float:
    """Worst time for a command to reach a landmark: its sleep period plus the air time."""
    return (settings.radio_sleep_period_s or 0.0) + AIR_LATENCY_S


def localizer_config(settings: Settings) -> LocalizerConfig:
    """The localizer's tuning for this site: with sleeping radios an identification probe
    waits up to the wake latency for its LED (frames meanwhile show an unknown state), so
    its timeout and the age of the frames it compares grow by as much."""
    base = LocalizerConfig()
    if settings.radio_sleep_period_s is None:
        return base
    ident = base.identification
    extra = wake_latency_s(settings)
    return dataclasses.replace(
        base,
        identification=dataclasses.replace(
            ident,
            led_timeout_s=ident.led_timeout_s + extra,
            reference_max_age_s=ident.reference_max_age_s + extra,
        ),
    )


def schedule_config(settings: Settings, period_s: float) -> ScheduleConfig:
    """The policy's tuning: decisions act after one plan period plus the wake latency, and
    a plan changes at most what the radio delivers in one period (`max_in_flight` commands
    per command latency: the awake air time; with sleeping radios the gateway takes a slot
    `lead_s` before a landmark's known wake-up, so a command holds it `lead_s` + the air
    time + half a poll interval)."""
    gw = gateway_config(settings)
    per_command_s = AIR_LATENCY_S
    if gw.sleep is not None:
        per_command_s = gw.sleep.lead_s + gw.sleep.air_s + gw.sleep.poll_interval_s / 2
    budget = max(round(gw.max_in_flight * period_s / per_command_s), 2)
    return ScheduleConfig(latency_s=period_s + wake_latency_s(settings), max_switches=budget)


def wake_window(settings: Settings, *, opened_s: float | None = None) -> WakeWindow | None:
    """The wake window of sleeping radios while robots identify (None: awake radios);
    open from the start when the gateway's start-up broadcast set `ST` = `opened_s`, the
    window's own."""
    if settings.radio_sleep_period_s is None:
        return None
    config = WakeWindowConfig(normal_wake_s=SleepConfig(settings.radio_sleep_period_s).wake_s)
    return WakeWindow(config, opened=opened_s == config.identify_wake_s)


def gateway_config(settings: Settings) -> GatewayConfig:
    """The gateway's tuning for this site: its battery polls, the landmarks' sleep (and the
    wake window the start-up sweep opens by one broadcast, as robots identify after it)."""
    sleep = settings.radio_sleep_period_s
    return GatewayConfig(
        battery=BatteryMonitorConfig(
            interval_s=settings.battery_interval_s,
            first_read_s=0.0 if sleep is None else FIRST_BATTERY_READ_S,
        ),
        sleep=None if sleep is None else SleepConfig(sleep),
        start_awake_s=(
            WakeWindowConfig().identify_wake_s
            if sleep is not None and settings.led_policy == "scheduled"  # the window closes it
            else None
        ),
    )


def xbee_config(settings: Settings) -> Any:
    """The XBee transport's timeouts: above the sleep period with sleeping landmarks."""
    from rf_gateway.xbee_transport import XBeeTransportConfig

    if settings.radio_sleep_period_s is None:
        return None
    sleep = SleepConfig(settings.radio_sleep_period_s)
    return XBeeTransportConfig(command_timeout_s=sleep.command_timeout_s)


def radio_sleep(settings: Settings) -> Any:
    """The virtual site's `lighting.energy.RadioSleep` (None: awake radios)."""
    if settings.radio_sleep_period_s is None:
        return None
    from lighting.energy import RadioSleep

    return RadioSleep(settings.radio_sleep_period_s)


def attach_scheduler(
    map: MapRepository,
    runners: Callable[[], Iterable[RobotRunner]],
    coordinator: LedCoordinator,
    clock_ns: Callable[[], int],
    settings: Settings,
    *,
    period_s: float = 0.25,
    routes: Callable[[str], tuple[tuple[float, float], ...]] | None = None,
) -> LedScheduler:
    """Build and start the scheduler of a site whose `led_policy` is `scheduled`: the map's
    landmarks that the coordinator's gateway controls, the live robots (and their routes
    where the fleet knows them)."""
    gateway = coordinator.gateway
    cache: dict[str, Any] = {}
    map.add_listener(lambda _landmarks: cache.clear())

    def landmarks() -> tuple[list[int], np.ndarray[Any, np.dtype[np.float64]]]:
        controlled = frozenset(gateway.landmarks)
        if cache.get("controlled") != controlled:
            lmap = map.landmark_map()
            ids = [int(i) for i in lmap.ids if int(i) in controlled]
            rows = [lmap.index_of(i) for i in ids]
            positions = np.asarray(lmap.positions, dtype=np.float64)[rows].reshape(-1, 3)
            cache.update(controlled=controlled, value=(ids, positions))
        value: tuple[list[int], np.ndarray[Any, np.dtype[np.float64]]] = cache["value"]
        return value

    def floors() -> dict[int, str]:
        if "floors" not in cache:
            cache["floors"] = {lm.id: lm.floor for lm in map.list()}
        value: dict[int, str] = cache["floors"]
        return value

    return make_scheduler(
        landmarks,
        runners,
        coordinator,
        clock_ns,
        settings,
        period_s=period_s,
        routes=routes,
        floors=floors,
    )


def make_scheduler(
    landmarks: Callable[[], tuple[list[int], np.ndarray[Any, np.dtype[np.float64]]]],
    runners: Callable[[], Iterable[RobotRunner]],
    coordinator: LedCoordinator,
    clock_ns: Callable[[], int],
    settings: Settings,
    *,
    period_s: float = 0.25,
    routes: Callable[[str], tuple[tuple[float, float], ...]] | None = None,
    floors: Callable[[], Mapping[int, str]] | None = None,
) -> LedScheduler:
    """A started scheduler whose plans become the coordinator's normal state (planned per
    floor when `floors` maps landmark IDs to floors)."""
    by_name: dict[str, float] = {}

    def max_speed(name: str) -> float:
        if name not in by_name:
            by_name.update({r.name: float(r.geometry.max_speed) for r in runners()})
        return by_name.get(name, 1.0)

    gateway = coordinator.gateway
    window = wake_window(settings, opened_s=gateway.start_awake_s)

    async def set_awake(seconds: float) -> object:
        normal = window is not None and seconds <= window.config.normal_wake_s
        priority = Priority.HOUSEKEEPING if normal else Priority.IDENTIFY
        return await gateway.set_awake_time(gateway.landmarks, seconds, priority=priority)

    scheduler = LedScheduler(
        landmarks,
        runners,
        max_speed,
        lambda: gateway.leds,
        clock_ns,
        config=schedule_config(settings, period_s),
        period_s=period_s,
        on_plan=lambda plan: coordinator.renormal(),
        set_awake=None if window is None else set_awake,
        wake_window=window,
        routes=routes,
        floors=floors,
    )
    coordinator.normal = scheduler.lit_ids
    scheduler.start()
    return scheduler
