"""The simulated transport: the virtual site's radio (`sim.radio.SimRadio`) behind `Transport`."""

from __future__ import annotations

import asyncio
from typing import Protocol

from rf_gateway.errors import RadioTimeout, TransportUnavailable
from rf_gateway.transport import DiscoveredRadio, StateReporter, normalize_address


class SimRadioLike(Protocol):
    """What `sim.radio.SimRadio` offers (docs/architecture.md)."""

    async def set_pin(self, address: str, high: bool) -> bool: ...

    async def read_supply_mv(self, address: str) -> int | None: ...

    async def set_awake_time(self, address: str, seconds: float) -> bool: ...

    async def discover(self) -> list[tuple[str, str]]: ...


def _radio_float(radio: object, name: str, default: float) -> float:
    value = getattr(radio, name, default)
    return float(value) if isinstance(value, int | float) else default


class SimTransport(StateReporter):
    """`Transport` over a simulated radio.

    Args:
        radio: the virtual site's radio (a `SimRadio`).
        command_timeout_s: longest wait for one answer; a command not acknowledged (False /
            None from the radio) or not answered in time raises `RadioTimeout`. Default: the
            radio's own `timeout_s` plus 0.2 s (0.5 s when it has none), plus its
            `sleep_period_s` (a sleeping landmark's command waits for its wake-up).
    """

    def __init__(self, radio: SimRadioLike, *, command_timeout_s: float | None = None) -> None:
        super().__init__()
        self.radio = radio
        if command_timeout_s is None:
            command_timeout_s = (
                _radio_float(radio, "timeout_s", 0.3)
                + 0.2
                + _radio_float(radio, "sleep_period_s", 0.0)
            )
        self.command_timeout_s = command_timeout_s

    async def open(self) -> None:
        self._set_state("open")

    async def close(self) -> None:
        self._set_state("closed")

    def _check_open(self) -> None:
        if self._state != "open":
            raise TransportUnavailable(f"simulated radio is {self._state}")

    async def set_pin(self, address: str, high: bool) -> None:
        address = normalize_address(address)
        self._check_open()
        try:
            ok = await asyncio.wait_for(self.radio.set_pin(address, high), self.command_timeout_s)
        except TimeoutError:
            raise RadioTimeout(address) from None
        if not ok:
            raise RadioTimeout(address, f"radio {address} did not acknowledge")

    async def set_awake_time(self, address: str, seconds: float) -> None:
        address = normalize_address(address)
        self._check_open()
        try:
            ok = await asyncio.wait_for(
                self.radio.set_awake_time(address, seconds), self.command_timeout_s
            )
        except TimeoutError:
            raise RadioTimeout(address) from None
        if not ok:
            raise RadioTimeout(address, f"radio {address} did not acknowledge")

    async def broadcast_pin(self, high: bool) -> None:
        """`BroadcastTransport.broadcast_pin` (nothing when the radio cannot)."""
        self._check_open()
        send = getattr(self.radio, "broadcast_pin", None)
        if send is not None:
            await send(high)

    async def broadcast_awake_time(self, seconds: float) -> None:
        """`BroadcastTransport.broadcast_awake_time` (nothing when the radio cannot)."""
        self._check_open()
        send = getattr(self.radio, "broadcast_awake_time", None)
        if send is not None:
            await send(seconds)

    async def read_pin(self, address: str) -> bool:
        """`BroadcastTransport.read_pin` (RadioTimeout when the radio cannot read it)."""
        address = normalize_address(address)
        self._check_open()
        read = getattr(self.radio, "read_pin", None)
        if read is None:
            raise RadioTimeout(address, f"radio {address}: pin not readable")
        try:
            level = await asyncio.wait_for(read(address), self.command_timeout_s)
        except TimeoutError:
            raise RadioTimeout(address) from None
        if level is None:
            raise RadioTimeout(address)
        return bool(level)

    async def read_supply_mv(self, address: str) -> int:
        address = normalize_address(address)
        self._check_open()
        try:
            mv = await asyncio.wait_for(self.radio.read_supply_mv(address), self.command_timeout_s)
        except TimeoutError:
            raise RadioTimeout(address) from None
        if mv is None:
            raise RadioTimeout(address)
        return int(mv)

    async def discover(self) -> list[DiscoveredRadio]:
        self._check_open()
        found = await self.radio.discover()
        radios = [
            DiscoveredRadio(normalize_address(a, source="simulated radio"), ni) for a, ni in found
        ]
        return sorted(radios, key=lambda r: r.address)
