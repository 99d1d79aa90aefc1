"""What the gateway reads from the landmarks: each one's supply voltage (the battery
schedule, low-battery events) and the radios that answer discovery. `LandmarkReads` is a
part of `Gateway` (it uses the gateway's command path and listeners)."""

from __future__ import annotations

import asyncio
from collections.abc import Awaitable, Callable
from typing import TypeVar

from pubsub.bus import Bus
from rf_gateway.battery import BatteryHistory, BatteryReading, read_all
from rf_gateway.config import GatewayConfig
from rf_gateway.events import GatewayEvent, LowBattery
from rf_gateway.scheduler import Priority, PrioritySlots
from rf_gateway.transport import DiscoveredRadio, Transport

T = TypeVar("T")


class LandmarkReads:
    """Supply reads and discovery of `Gateway` (module docstring); the attributes and
    methods declared here are the gateway's."""

    transport: Transport
    config: GatewayConfig
    clock_ns: Callable[[], int]
    batteries: BatteryHistory
    _addresses: dict[int, str]
    _slots: PrioritySlots
    _sweep_lock: asyncio.Lock
    _battery_listeners: list[Callable[[BatteryReading], None]]
    _events_hub: Bus[GatewayEvent]

    def address_of(self, landmark_id: int) -> str:
        raise NotImplementedError

    async def _command(self, lid: int, priority: Priority, send: Callable[[], Awaitable[T]]) -> T:
        raise NotImplementedError

    async def battery(self, landmark_id: int) -> BatteryReading:
        """Read one landmark's supply now (battery-poll priority), record it, tell the
        battery listeners, and raise a LowBattery event at or below the threshold; raises
        as `set_leds`."""
        address = self.address_of(landmark_id)
        mv = await self._command(
            landmark_id, Priority.BATTERY, lambda: self.transport.read_supply_mv(address)
        )
        reading = self.batteries.add(landmark_id, self.clock_ns(), int(mv))
        for listener in list(self._battery_listeners):
            listener(reading)
        if self.batteries.became_low(reading):
            event = LowBattery(reading.t_ns, landmark_id, reading.supply_mv, reading.days_left)
            self._events_hub.publish(event)
        return reading

    async def poll_batteries(self) -> list[BatteryReading]:
        """Read every landmark once (a landmark that fails is skipped, its event raised)."""
        return await read_all(self.battery, sorted(self._addresses), self.config.max_in_flight)

    async def _battery_loop(self) -> None:
        if self.config.light_all_on_start:
            async with self._sweep_lock:  # after the start-up sweep
                pass
        if self.config.battery.first_read_s > 0:
            await asyncio.sleep(self.config.battery.first_read_s)
        while self.config.battery.interval_s is not None:
            await self.poll_batteries()
            await asyncio.sleep(self.config.battery.interval_s)

    async def discover(self) -> list[DiscoveredRadio]:
        """Radios that answer node discovery (`discover_rounds` of them, merged) and are not
        in the landmark map, by address."""
        found: dict[str, DiscoveredRadio] = {}
        for _ in range(max(1, self.config.discover_rounds)):
            async with self._slots.slot(Priority.HOUSEKEEPING):
                for r in await self.transport.discover():
                    found.setdefault(r.address, r)
        known = set(self._addresses.values())
        return [r for a, r in sorted(found.items()) if a not in known]
