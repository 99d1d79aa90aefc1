"""`SiteSupervisor`: watches the live site once a second, on the server's loop.

- A source thread that ended (the virtual site's clock or its localizer feed) is started
  again, with a `site_thread_restarted` event (`revive` of the source).
- A robot fed by the site itself (virtual or camera) whose localizer took neither a frame
  nor gave a pose for `STALL_S` is reported.

`problems()` lists what is wrong now, for `/healthz` (which answers 503 naming them).
"""

from __future__ import annotations

import asyncio
import logging
import time
from collections.abc import Callable, Iterable
from typing import Protocol, runtime_checkable

from live.events import EventHub
from live.robots import RobotRunner

log = logging.getLogger(__name__)
CHECK_S = 1.0
STALL_S = 15.0
WATCHED_SOURCES = ("sim", "camera")


@runtime_checkable
class Revivable(Protocol):
    def dead_threads(self) -> list[str]: ...
    def revive(self) -> list[str]: ...


class SiteSupervisor:
    """See the module. `sources()` and `runners()` are read at each check."""

    def __init__(
        self,
        sources: Callable[[], Iterable[object]],
        runners: Callable[[], Iterable[RobotRunner]],
        events: EventHub,
        *,
        stall_s: float = STALL_S,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.sources, self.runners, self.events = sources, runners, events
        self.stall_s = stall_s
        self.clock = clock
        self.restarts = 0
        self._seen: dict[str, tuple[int, int, float]] = {}  # frames, poses, when they moved
        self._dead: list[str] = []

    def check(self) -> None:
        """One round: revive dead threads, note stalled robots."""
        dead: list[str] = []
        for source in self.sources():
            if not isinstance(source, Revivable):
                continue
            if source.dead_threads():
                revived = source.revive()
                self.restarts += len(revived)
                for name in revived:
                    self.events.emit(
                        "site_thread_restarted",
                        f"site thread {name} had stopped: started again",
                        data={"thread": name},
                    )
                dead += source.dead_threads()
        self._dead = dead
        now = self.clock()
        names = set()
        for r in self.runners():
            if r.source not in WATCHED_SOURCES:
                continue
            names.add(r.name)
            frames, poses, moved = self._seen.get(r.name, (-1, -1, now))
            if (r.frames, r.poses) != (frames, poses):
                moved = now
            self._seen[r.name] = (r.frames, r.poses, moved)
        for name in set(self._seen) - names:
            del self._seen[name]

    def problems(self) -> list[str]:
        """What is wrong with the live site now (empty: nothing)."""
        out = [f"site thread {name} is not running" for name in self._dead]
        now = self.clock()
        for name, (_, _, moved) in sorted(self._seen.items()):
            if now - moved > self.stall_s:
                out.append(f"robot {name}: no frame localized for {now - moved:.0f} s")
        return out

    async def run(self) -> None:
        while True:
            try:
                self.check()
            except Exception:
                log.exception("site supervisor: a check failed")
            await asyncio.sleep(CHECK_S)
