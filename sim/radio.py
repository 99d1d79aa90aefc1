"""The simulated radio link to the landmarks (what the RF gateway's sim transport wraps).

Each command takes a random latency, may be lost on the way out or back, and a landmark
that cannot answer (broken radio, flat battery, unknown address) lets the caller wait for a
timeout. A delivered command switches the world's LED at once; the cameras see it in their
next frame.

Sleeping radios (`sleep`, XBee cyclic sleep): a landmark wakes every `period_s` (each at its
own phase) and polls its parent, which has buffered the command meanwhile; the command is
delivered at that wake-up, so it waits up to one period before the usual latency. After a
command the landmark stays awake `wake_s` (XBee `ST`), polling every `poll_interval_s`, so
the commands that follow soon wait at most a poll interval.

Broadcasts (`broadcast_pin`, `broadcast_awake_time`: a remote AT command to the broadcast
address, not acknowledged): the parent buffers one broadcast for all its sleeping children
and each takes it at its next poll (or loses it), so one frame reaches the whole site within
a sleep period; `read_pin` reads a landmark's pin back.
"""

from __future__ import annotations

import asyncio
import math
from collections.abc import Callable

import numpy as np

from lighting.energy import RadioSleep
from sim.world import SimLandmark, World

_GOLDEN = (math.sqrt(5.0) - 1.0) / 2.0


class SimRadio:
    """Radio link to the landmarks of a `World`.

    Args:
        world: the landmarks.
        rng: draws latencies and losses.
        latency_s: (min, max) one-way-and-back latency of a delivered command, seconds.
        loss: probability that a packet is lost, each way.
        timeout_s: how long a caller waits for an answer that never comes, seconds (after
            the landmark's wake-up when it sleeps).
        discover_s: how long a node discovery listens, seconds.
        sleep: the landmarks' radios sleep in cycles (None: always awake); also sets the
            world's energy model to it.
    """

    def __init__(
        self,
        world: World,
        *,
        rng: np.random.Generator,
        latency_s: tuple[float, float] = (0.01, 0.04),
        loss: float = 0.02,
        timeout_s: float = 0.3,
        discover_s: float = 0.2,
        sleep: RadioSleep | None = None,
    ) -> None:
        lo, hi = latency_s
        if not 0 <= lo <= hi or not 0 <= loss < 1 or timeout_s < hi:
            raise ValueError(
                f"SimRadio: need 0 <= latency min <= max <= timeout and 0 <= loss < 1, "
                f"got latency {latency_s}, loss {loss}, timeout {timeout_s}"
            )
        self.world = world
        self.rng = rng
        self.latency_s = (float(lo), float(hi))
        self.loss = float(loss)
        self.timeout_s = float(timeout_s)
        self.discover_s = float(discover_s)
        self.sleep = sleep
        if world.energy is not None:
            world.energy.sleep = sleep
        self.messages = 0
        self._awake_until: dict[int, float] = {}
        self._wake_s: dict[int, float] = {}  # per landmark `ST` set over the air
        self._broadcasts: set[asyncio.Task[None]] = set()

    @property
    def sleep_period_s(self) -> float:
        """The longest a command waits for a landmark to wake, seconds (0: awake radios)."""
        return 0.0 if self.sleep is None else self.sleep.period_s

    def wake_delay_s(self, landmark_id: int, now_s: float) -> float:
        """Seconds from `now_s` until the landmark next polls its parent (0 when the radio
        never sleeps): within a poll interval while it is awake after a command, else at
        its next cyclic wake-up."""
        if self.sleep is None:
            return 0.0
        phase = (landmark_id * _GOLDEN % 1.0) * self.sleep.period_s
        if now_s < self._awake_until.get(landmark_id, -math.inf):
            return (phase - now_s) % self.sleep.poll_interval_s
        return (phase - now_s) % self.sleep.period_s

    def wake_s(self, landmark_id: int) -> float:
        """The landmark's time awake after a message (`ST`), seconds (0: awake radios)."""
        if self.sleep is None:
            return 0.0
        return self._wake_s.get(landmark_id, self.sleep.wake_s)

    def _delivered(self, landmark_id: int, now_s: float, new_wake_s: float | None = None) -> None:
        """Account a delivered command and keep the radio awake `wake_s` after it (a command
        setting `ST` restarts the timer with `new_wake_s`)."""
        extra = 0.0
        if self.sleep is not None:
            before = self._awake_until.get(landmark_id, now_s)
            if new_wake_s is not None:
                self._wake_s[landmark_id] = new_wake_s
            until = now_s + self.wake_s(landmark_id)
            extra = max(until - max(before, now_s), 0.0)
            if new_wake_s is not None and until < before:  # a shorter ST: asleep earlier
                extra = until - before  # the awake time charged beyond it is refunded
            self._awake_until[landmark_id] = until if new_wake_s is not None else max(until, before)
        self.messages += 1
        self.world.radio_message(landmark_id, extra)

    def _lost(self) -> bool:
        return bool(self.rng.random() < self.loss)

    async def _exchange(self, address: str, new_wake_s: float | None = None) -> SimLandmark | None:
        """Deliver one command: the landmark if it arrived; None after a timeout otherwise.

        The command's effect is applied by the caller between delivery and the answer.
        """
        latency = float(self.rng.uniform(*self.latency_s))
        lm = self.world.by_address(address)
        loop = asyncio.get_running_loop()
        wait = 0.0 if lm is None else self.wake_delay_s(lm.id, loop.time() + latency / 4)
        if lm is None or not lm.reachable or self._lost():
            await asyncio.sleep(wait + self.timeout_s)  # from when it would have arrived
            return None
        await asyncio.sleep(wait + latency / 2)
        self._delivered(lm.id, loop.time(), new_wake_s)
        return lm

    async def _answer(self, latency_started: float) -> bool:
        """The answer's way back: True when it arrives."""
        if self._lost():
            await asyncio.sleep(self.timeout_s - latency_started)
            return False
        await asyncio.sleep(float(self.rng.uniform(*self.latency_s)) / 2)
        return True

    async def set_pin(self, address: str, high: bool) -> bool:
        """Drive a landmark's LED pin; True when the acknowledgement arrives.

        A lost acknowledgement returns False although the LED did switch (as on a real
        radio).
        """
        lm = await self._exchange(address)
        if lm is None:
            return False
        self.world.set_led(lm.id, high)
        return await self._answer(self.latency_s[0] / 2)

    async def read_supply_mv(self, address: str) -> int | None:
        """The landmark's supply voltage in mV, or None when it does not answer."""
        lm = await self._exchange(address)
        if lm is None:
            return None
        mv = round(lm.battery.supply_v(lm.led_on) * 1000.0)
        return mv if await self._answer(self.latency_s[0] / 2) else None

    async def set_awake_time(self, address: str, seconds: float) -> bool:
        """Set a landmark's time awake after each message (XBee `ST`, applied at once, so
        it already holds after this command); True when acknowledged."""
        if not 0.0 <= seconds <= 65.0:
            raise ValueError(f"set_awake_time: ST 0 .. 65 s, got {seconds}")
        lm = await self._exchange(address, float(seconds))
        if lm is None:
            return False
        return await self._answer(self.latency_s[0] / 2)

    async def read_pin(self, address: str) -> bool | None:
        """Whether the landmark's LED pin is high, or None when it does not answer."""
        lm = await self._exchange(address)
        if lm is None:
            return None
        level = lm.led_on
        return level if await self._answer(self.latency_s[0] / 2) else None

    async def broadcast_pin(self, high: bool) -> None:
        """Drive every landmark's LED pin by one unacknowledged broadcast (as
        `broadcast_awake_time`)."""
        await self._broadcast(lambda lm: self.world.set_led(lm.id, high), None)

    async def broadcast_awake_time(self, seconds: float) -> None:
        """Set every landmark's `ST` by one unacknowledged broadcast: returns once it is on
        the air; each landmark takes it at its next poll unless the packet is lost."""
        if not 0.0 <= seconds <= 65.0:
            raise ValueError(f"broadcast_awake_time: ST 0 .. 65 s, got {seconds}")
        await self._broadcast(lambda lm: None, float(seconds))

    async def _broadcast(
        self, apply: Callable[[SimLandmark], None], new_wake_s: float | None
    ) -> None:
        loop = asyncio.get_running_loop()
        t0 = loop.time()
        for lm in sorted(self.world.landmarks.values(), key=lambda lm: lm.id):
            latency = float(self.rng.uniform(*self.latency_s))
            if not lm.reachable or self._lost():
                continue
            at = self.wake_delay_s(lm.id, t0 + latency / 4) + latency / 2
            task = loop.create_task(self._broadcast_to(lm, at, apply, new_wake_s))
            self._broadcasts.add(task)
            task.add_done_callback(self._broadcasts.discard)
        await asyncio.sleep(self.latency_s[0] / 2)

    async def _broadcast_to(
        self,
        lm: SimLandmark,
        delay_s: float,
        apply: Callable[[SimLandmark], None],
        new_wake_s: float | None,
    ) -> None:
        await asyncio.sleep(delay_s)
        self._delivered(lm.id, asyncio.get_running_loop().time(), new_wake_s)
        apply(lm)

    async def discover(self) -> list[tuple[str, str]]:
        """(address, node identifier) of every landmark that answers a node discovery."""
        await asyncio.sleep(self.discover_s)
        return [
            (lm.address, lm.node_id)
            for lm in sorted(self.world.landmarks.values(), key=lambda lm: lm.id)
            if lm.reachable and not self._lost()
        ]
