"""The gateway's start-up: every LED lit before robots identify.

With awake radios, one command per landmark (`Gateway._apply`). With sleeping landmarks
that can be reached by broadcast (`GatewayConfig.start_awake_s`, a `BroadcastTransport`):
one broadcast lights every LED, the LEDs are published lit once every landmark has polled
(*believed*), a second broadcast opens the wake window (`ST`), and each believed LED is
read back at housekeeping priority afterwards (docs/rf_gateway.md, "Start-up by
broadcast"). `StartupSweep` is a part of `Gateway` (it uses the gateway's LED state).
"""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Awaitable, Callable, Mapping
from contextlib import AbstractAsyncContextManager
from functools import partial
from typing import TypeVar

from localizer.events import LedsChanged
from rf_gateway.config import GatewayConfig, GatewayStats
from rf_gateway.errors import RfGatewayError
from rf_gateway.scheduler import Priority
from rf_gateway.transport import BroadcastTransport, Transport

log = logging.getLogger("rf_gateway.gateway")
T = TypeVar("T")


class StartupSweep:
    """The start-up sweep of `Gateway` (module docstring); the attributes and methods
    declared here are the gateway's."""

    transport: Transport
    config: GatewayConfig
    stats: GatewayStats
    clock_ns: Callable[[], int]
    _addresses: dict[int, str]
    _desired: dict[int, tuple[bool, int]]
    _confirmed: dict[int, tuple[bool, int, int]]
    _syncers: dict[int, asyncio.Task[None]]
    _seq: int
    _sweep_lock: asyncio.Lock
    _broadcasting: frozenset[int]
    _believed: set[int]

    def _publish_state(self, *, announce: bool = False) -> LedsChanged:
        raise NotImplementedError

    async def _apply(self, targets: Mapping[int, bool], priority: Priority) -> LedsChanged:
        raise NotImplementedError

    async def _command(self, lid: int, priority: Priority, send: Callable[[], Awaitable[T]]) -> T:
        raise NotImplementedError

    def sweep(self) -> AbstractAsyncContextManager[object]:
        raise NotImplementedError

    @property
    def start_awake_s(self) -> float | None:
        """The `ST` the start-up sweep broadcasts to every landmark first (None: none:
        awake radios, no `start_awake_s`, or a transport that cannot broadcast)."""
        cfg = self.config
        if cfg.sleep is None or cfg.start_awake_s is None or not cfg.light_all_on_start:
            return None
        return cfg.start_awake_s if isinstance(self.transport, BroadcastTransport) else None

    async def _light_all(self) -> None:
        broadcast = False
        try:
            broadcast = await self._broadcast_start()
            if not broadcast:
                await self._apply(dict.fromkeys(self._addresses, True), Priority.IDENTIFY)
        except Exception as exc:  # logged; the state confirmed so far is published
            log.warning("lighting every landmark at start: %s", exc)
        finally:
            self._sweep_lock.release()
        if broadcast:
            await self._verify_believed()

    async def _broadcast_start(self) -> bool:
        """Start-up with sleeping landmarks (`start_awake_s`): light every LED by one
        broadcast, wait until every landmark has polled once (`broadcast_wait_s`), publish
        them lit (*believed*: robots identify at once) and open the wake window by a second
        broadcast (`ST`; the landmarks are awake after the first). False: no broadcast
        (the start-up sweep is one command per landmark)."""
        seconds, sleep, transport = self.start_awake_s, self.config.sleep, self.transport
        if seconds is None or sleep is None or not isinstance(transport, BroadcastTransport):
            return False
        ids = frozenset(self._addresses)
        self._broadcasting = ids
        self._publish_state(announce=True)  # unknown until every landmark took it
        try:
            await transport.broadcast_pin(True)
            self.stats.commands += 1
            self.stats.broadcasts += 1
            await asyncio.sleep(sleep.broadcast_wait_s)
        except RfGatewayError as exc:
            log.warning("broadcasting LED on to every landmark: %s", exc)
            return False
        finally:
            self._broadcasting = frozenset()
        t_ns = self.clock_ns()
        for lid in ids - set(self._syncers):
            self._seq += 1
            self._desired[lid] = (True, self._seq)
            self._confirmed[lid] = (True, self._seq, t_ns)
            self._believed.add(lid)
        self._publish_state()
        try:
            await transport.broadcast_awake_time(seconds)
            self.stats.commands += 1
            self.stats.broadcasts += 1
        except RfGatewayError as exc:  # identification probes are then only slower
            log.warning("broadcasting ST to every landmark: %s", exc)
        return True

    async def _verify_believed(self) -> None:
        """Read back each LED believed lit since the start-up broadcast (housekeeping
        priority: after the robots' probes). One that missed the broadcast is switched as
        believed (announced, as any change); a confirmed command settles a landmark too. A
        missed one is dark while believed lit: a steady spot-less landmark, which neither
        identification (it compares switches) nor tracking (an occluded landmark) mistakes
        for anything."""
        transport = self.transport
        if not isinstance(transport, BroadcastTransport):
            return

        async def one(lid: int) -> None:
            seq = self._confirmed.get(lid, (False, 0, 0))[1]
            send = partial(transport.read_pin, self._addresses[lid])
            try:
                high = await self._command(lid, Priority.HOUSEKEEPING, send)
            except RfGatewayError:  # marked unreachable by `_command`: its LED is unknown
                if lid in self._believed and self._confirmed.get(lid, (0, -1))[1] == seq:
                    self._believed.discard(lid)
                    del self._confirmed[lid]
                    self._publish_state()
                return
            confirmed = self._confirmed.get(lid)
            if lid not in self._believed or confirmed is None or confirmed[1] != seq:
                return  # a command settled it meanwhile
            self._believed.discard(lid)
            if high != confirmed[0]:
                self.stats.broadcast_missed += 1
                del self._confirmed[lid]  # unknown: sent again
                async with self.sweep():
                    await self._apply({lid: confirmed[0]}, Priority.HOUSEKEEPING)

        await asyncio.gather(*(one(lid) for lid in sorted(self._believed)), return_exceptions=True)
