"""A scripted in-memory `Transport` for the gateway's logic tests (the XBee path is tested
through digi-xbee against the emulator, never with this)."""

from __future__ import annotations

import asyncio
from collections.abc import Callable
from dataclasses import dataclass, field

from rf_gateway.errors import RadioTimeout, RemoteCommandError, TransportUnavailable
from rf_gateway.transport import DiscoveredRadio, TransportState


@dataclass
class FakeClock:
    now: int = 0

    def __call__(self) -> int:
        return self.now


@dataclass
class ScriptedTransport:
    """Applies pins instantly (after `delay_s`), advancing `clock` by `tick_ns` per ack.

    Attributes:
        fail_next: address -> how many of the next commands time out.
        dead: addresses that never answer (RadioTimeout).
        refused: addresses answering status 2 (invalid command).
        log: every command received, ("pin", address, high) / ("mv", address).
    """

    clock: FakeClock = field(default_factory=FakeClock)
    tick_ns: int = 1000
    delay_s: float = 0.0
    pins: dict[str, bool] = field(default_factory=dict)
    supply_mv: dict[str, int] = field(default_factory=dict)
    fail_next: dict[str, int] = field(default_factory=dict)
    dead: set[str] = field(default_factory=set)
    refused: set[str] = field(default_factory=set)
    radios: list[DiscoveredRadio] = field(default_factory=list)
    log: list[tuple[object, ...]] = field(default_factory=list)
    _state: TransportState = "closed"
    _listeners: list[Callable[[TransportState], None]] = field(default_factory=list)

    @property
    def state(self) -> TransportState:
        return self._state

    def set_state(self, state: TransportState) -> None:
        self._state = state
        for cb in self._listeners:
            cb(state)

    def on_state_change(self, callback: Callable[[TransportState], None]) -> None:
        self._listeners.append(callback)

    async def open(self) -> None:
        self.set_state("open")

    async def close(self) -> None:
        self.set_state("closed")

    async def _answer(self, address: str) -> None:
        if self._state != "open":
            raise TransportUnavailable("closed")
        if self.delay_s:
            await asyncio.sleep(self.delay_s)
        if address in self.dead:
            raise RadioTimeout(address)
        if address in self.refused:
            raise RemoteCommandError(address, 2)
        if self.fail_next.get(address, 0) > 0:
            self.fail_next[address] -= 1
            raise RadioTimeout(address)

    async def set_pin(self, address: str, high: bool) -> None:
        self.log.append(("pin", address, high))
        await self._answer(address)
        self.pins[address] = high
        self.clock.now += self.tick_ns

    async def read_supply_mv(self, address: str) -> int:
        self.log.append(("mv", address))
        await self._answer(address)
        self.clock.now += self.tick_ns
        return self.supply_mv.get(address, 3000)

    async def set_awake_time(self, address: str, seconds: float) -> None:
        self.log.append(("st", address, seconds))
        await self._answer(address)
        self.clock.now += self.tick_ns

    async def discover(self) -> list[DiscoveredRadio]:
        return list(self.radios)
