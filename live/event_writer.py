"""`EventWriter`: site events go to the database from one writer thread, never from the
thread that raised them (a robot's localizer, the radio's loop).

`submit` only queues (bounded: past `maxsize` waiting events the newest is dropped and
counted); the writer stores each event and hands it to `publish` with its database id. When
the database fails (down, locked by another process, disk full) the event is published at
once without an id (id 0: the stream still shows it), kept, and stored when the database is
back (retried with a growing pause, up to `MAX_RETRY_S`); `healthy` and `problem` say so for
`/healthz`; one log line when writes start failing and one when they work again.
"""

from __future__ import annotations

import logging
import queue
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from datetime import datetime
from typing import Any

from store.log import EventLog
from store.models import utcnow

log = logging.getLogger(__name__)
MAX_RETRY_S = 2.0


@dataclass
class PendingEvent:
    kind: str
    message: str
    robot: str | None
    landmark_id: int | None
    data: dict[str, Any]
    t: datetime = field(default_factory=utcnow)
    published: bool = False


class EventWriter:
    """See the module. `publish(pending, id)` is called on the writer thread."""

    def __init__(
        self,
        event_log: EventLog,
        publish: Callable[[PendingEvent, int], None],
        *,
        maxsize: int = 1024,
    ) -> None:
        self.log = event_log
        self.publish = publish
        self.dropped = 0
        self.written = 0
        self.store_failures = 0
        self.problem: str | None = None
        self.failing_since: float | None = None
        self._queue: queue.Queue[PendingEvent | None] = queue.Queue(maxsize)
        self._retry: deque[PendingEvent] = deque()
        self._idle = threading.Condition()
        self._busy = 0
        self._thread = threading.Thread(target=self._run, name="event-writer", daemon=True)
        self._thread.start()

    @property
    def healthy(self) -> bool:
        return self.problem is None

    def submit(self, event: PendingEvent) -> bool:
        """Queue `event` (never blocks); False when the queue was full and it was dropped."""
        with self._idle:
            self._busy += 1
        try:
            self._queue.put_nowait(event)
        except queue.Full:
            with self._idle:
                self._busy -= 1
                self._idle.notify_all()
            self.dropped += 1
            if self.dropped == 1 or self.dropped % 1000 == 0:
                log.error("event queue full: %d events dropped so far", self.dropped)
            return False
        return True

    def flush(self, timeout_s: float = 2.0) -> bool:
        """Wait until every queued event is stored (or, the database failing, kept for
        later); False on timeout."""
        deadline = time.monotonic() + timeout_s
        with self._idle:
            while self._busy > 0:
                left = deadline - time.monotonic()
                if left <= 0:
                    return False
                self._idle.wait(left)
        return True

    def close(self, timeout_s: float = 5.0) -> None:
        """Store what is queued (waiting at most `timeout_s`) and stop the thread."""
        self.flush(timeout_s)
        try:
            self._queue.put(None, timeout=1.0)
        except queue.Full:
            return
        self._thread.join(timeout_s)

    def _store(self, ev: PendingEvent) -> bool:
        try:
            rec = self.log.add_event(
                ev.kind,
                ev.message,
                robot=ev.robot,
                landmark_id=ev.landmark_id,
                data=ev.data,
                t=ev.t,
            )
        except Exception as exc:  # the database is down, locked or full: keep it for later
            self.store_failures += 1
            if self.problem is None:
                first = str(getattr(exc, "orig", None) or exc).splitlines()[0][:160]
                self.problem = f"database unavailable: events cannot be stored ({first})"
                self.failing_since = time.monotonic()
                log.error("%s; they are kept and stored when it is back", self.problem)
            if not ev.published:
                ev.published = True
                self.publish(ev, 0)
            return False
        if self.problem is not None:
            took = time.monotonic() - (self.failing_since or time.monotonic())
            log.warning(
                "events are stored again (after %.1f s; %d waiting)", took, len(self._retry)
            )
            self.problem = self.failing_since = None
        self.written += 1
        if not ev.published:
            ev.published = True
            self.publish(ev, rec.id or 0)
        return True

    def _run(self) -> None:
        pause, next_try = 0.25, 0.0
        while True:
            timeout = max(0.0, next_try - time.monotonic()) if self._retry else None
            try:
                item = self._queue.get(timeout=timeout)
                got = True
            except queue.Empty:
                item, got = None, False
            if got and item is None:
                return
            if item is not None:
                self._retry.append(item)  # in order, behind those waiting
                if self.problem is not None and not item.published:  # shown now, stored later
                    item.published = True
                    self.publish(item, 0)
                if len(self._retry) > self._queue.maxsize:  # keep at most a queue's worth
                    self._retry.popleft()
                    self.dropped += 1
            while self._retry and time.monotonic() >= next_try:
                if self._store(self._retry[0]):
                    self._retry.popleft()
                    pause = 0.25
                    continue
                for waiting in self._retry:  # shown at once, stored later
                    if not waiting.published:
                        waiting.published = True
                        self.publish(waiting, 0)
                pause = min(MAX_RETRY_S, pause * 2)
                next_try = time.monotonic() + pause
            if got:
                self._done()

    def _done(self) -> None:
        with self._idle:
            self._busy -= 1
            self._idle.notify_all()
