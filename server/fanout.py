"""WebSocket fan-out of poses: encode each batch once, send the same text to every client.

One `PoseFanout` per app runs on the server's event loop with a single pose-bus
subscription. It waits for poses, lingers `flush_s` so that poses computed together (every
robot of a site step) travel in one message, encodes the batch once per robot filter (all
unfiltered clients share one string) and queues it to each client. Each client has its own
bounded queue of messages and its own sender task: a client whose socket backs up (TCP flow
control) loses its oldest messages (counted in `dropped_poses`) and never delays the others.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
from collections import deque
from collections.abc import Iterable

from live.poses import PoseUpdate
from pubsub.bus import Bus, Subscription

log = logging.getLogger(__name__)
DEFAULT_FLUSH_S = 0.005
DEFAULT_CLIENT_QUEUE = 256
"""Messages per client: at 5 ms batches, one to a few seconds of poses (rides out a hiccup)."""


class FanoutClient:
    """One WebSocket client's queue of encoded messages (bounded; oldest dropped).

    Attributes:
        robots: the robots this client wants (None: all).
        dropped_poses: poses lost because this client fell behind.
        sent_poses: poses handed to the client's sender.
    """

    def __init__(self, robots: frozenset[str] | None, maxsize: int) -> None:
        if maxsize < 1:
            raise ValueError(f"client queue size must be >= 1, got {maxsize}")
        self.robots = robots
        self.maxsize = maxsize
        self.dropped_poses = 0
        self.sent_poses = 0
        self.closed = False
        self._items: deque[tuple[str, int]] = deque()
        self._ready = asyncio.Event()

    def put(self, message: str, n_poses: int) -> int:
        """Queue one message of `n_poses` poses; returns the poses dropped to make room."""
        dropped = 0
        if len(self._items) >= self.maxsize:
            dropped = self._items.popleft()[1]
            self.dropped_poses += dropped
        self._items.append((message, n_poses))
        self._ready.set()
        return dropped

    async def get(self) -> str | None:
        """The oldest queued message, waiting for one; None once closed and empty."""
        while not self._items:
            if self.closed:
                return None
            self._ready.clear()
            await self._ready.wait()
        message, n = self._items.popleft()
        self.sent_poses += n
        return message

    def close(self) -> None:
        self.closed = True
        self._ready.set()


def encode_batch(poses: Iterable[PoseUpdate]) -> str:
    """The WebSocket message for some poses: a JSON array of `PoseUpdate.json`, oldest first."""
    return "[" + ",".join(p.json for p in poses) + "]"


class PoseFanout:
    """Fan the pose bus out to WebSocket clients (create and run on the server loop).

    Args:
        bus: the pose bus.
        flush_s: how long to gather poses after the first of a batch arrives, seconds
            (bounds the messages per client to 1 / flush_s a second; adds at most that much
            latency).
        bus_queue: poses buffered between the bus and this task.

    Attributes:
        messages: messages queued over all clients; dropped_poses: poses lost by clients that
        fell behind (over all clients, ever).
    """

    def __init__(
        self, bus: Bus[PoseUpdate], *, flush_s: float = DEFAULT_FLUSH_S, bus_queue: int = 4096
    ) -> None:
        self.bus = bus
        self.flush_s = flush_s
        self.bus_queue = bus_queue
        self.clients: list[FanoutClient] = []
        self.messages = 0
        self.dropped_poses = 0
        self._sub: Subscription[PoseUpdate] | None = None
        self._task: asyncio.Task[None] | None = None

    def start(self) -> None:
        self._sub = self.bus.subscribe(self.bus_queue)
        self._task = asyncio.get_running_loop().create_task(self._run(self._sub))

    async def stop(self) -> None:
        if self._sub is not None:
            self._sub.close()
        if self._task is not None:
            self._task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._task
        for c in self.clients:
            c.close()
        self.clients = []

    def add_client(
        self, robots: Iterable[str] | None = None, maxsize: int = DEFAULT_CLIENT_QUEUE
    ) -> FanoutClient:
        """A new client receiving every robot's poses (or those of `robots`) from now on."""
        client = FanoutClient(frozenset(robots) if robots else None, maxsize)
        self.clients = [*self.clients, client]
        return client

    def remove_client(self, client: FanoutClient) -> None:
        client.close()
        self.clients = [c for c in self.clients if c is not client]

    def dispatch(self, batch: list[PoseUpdate]) -> None:
        """Encode `batch` once per distinct robot filter and queue it to every client."""
        encoded: dict[frozenset[str] | None, tuple[str, int]] = {}
        for client in self.clients:
            key = client.robots
            msg = encoded.get(key)
            if msg is None:
                chosen = batch if key is None else [p for p in batch if p.robot in key]
                msg = (encode_batch(chosen), len(chosen))
                encoded[key] = msg
            if msg[1]:
                self.dropped_poses += client.put(*msg)
                self.messages += 1

    async def _run(self, sub: Subscription[PoseUpdate]) -> None:
        while not sub.closed:
            batch = await sub.get_batch()
            if not batch:
                continue
            if self.flush_s > 0:
                await asyncio.sleep(self.flush_s)
                batch += sub.drain()
            try:
                self.dispatch(batch)
            except Exception:  # never let one bad batch end every client's stream
                log.exception("pose fan-out failed on a batch of %d poses", len(batch))
