"""`SimSource`: the virtual site (`sim.virtual_site.VirtualSite`) as a `FrameSource` for its robots.

One thread steps the site at `step_hz` on the site clock (frames are rendered with the LEDs
lit at the call, so a short period keeps a frame's picture true to its timestamp); another
feeds the samples to the sink, skipping frames older than `max_frame_lag_s` when their turn
comes (odometry never is), so a slow localizer falls behind by frames, not by time.
An error feeding one sample is counted and logged (once per `ERROR_LOG_EVERY_S`), and the
feeding goes on; a thread that ends all the same is started again by `revive` (the live
site's supervisor calls it).
"""

from __future__ import annotations

import logging
import queue
import threading
import time
from collections.abc import Callable, Sequence

from localizer.events import FrameObserved
from sensors.sources import SensorEvent, SensorSink
from sim.robot import FloorArrival
from sim.virtual_site import SensorSample, VirtualSite

log = logging.getLogger(__name__)
ERROR_LOG_EVERY_S = 10.0


class SimSource:
    """Feed the virtual site's robots (a `FrameSource`).

    Args:
        site: the virtual site.
        clock_ns: the site clock.
        step_hz: site steps per second.
        max_frame_lag_s: frames later than this when delivered are skipped, seconds.

    Attributes:
        frames_skipped: frames skipped for being late.
    """

    def __init__(
        self,
        site: VirtualSite,
        clock_ns: Callable[[], int],
        *,
        step_hz: float = 100.0,
        max_frame_lag_s: float = 0.25,
    ) -> None:
        self.site = site
        self.clock_ns = clock_ns
        self.step_hz = step_hz
        self.max_frame_lag_s = max_frame_lag_s
        self.frames_skipped = 0
        self.on_floor: Callable[[str, FloorArrival], None] | None = None
        """Called (on the feeding thread, in time order with the samples) when a robot
        leaves the lift on a floor."""
        self.errors = 0
        self.restarts = 0
        self._sink: SensorSink | None = None
        self._error_logged_at = -ERROR_LOG_EVERY_S
        self._stop = threading.Event()
        self._samples: queue.SimpleQueue[list[SensorSample] | None] = queue.SimpleQueue()
        self._threads: list[threading.Thread] = []

    @property
    def robots(self) -> Sequence[str]:
        return list(self.site.robot_names)

    def start(self, sink: SensorSink) -> None:
        self._sink = sink
        self._threads = [
            threading.Thread(target=self._run_clock, name="site-clock", daemon=True),
            threading.Thread(target=self._feed, args=(sink,), name="site-localizers", daemon=True),
        ]
        for t in self._threads:
            t.start()

    def dead_threads(self) -> list[str]:
        """Names of this source's threads that ended while it runs (none, normally)."""
        if self._stop.is_set():
            return []
        return [t.name for t in self._threads if not t.is_alive()]

    def revive(self) -> list[str]:
        """Start again the threads that ended (`dead_threads`); their names."""
        dead = self.dead_threads()
        if not dead or self._sink is None:
            return []
        sink = self._sink
        targets: dict[str, Callable[[], None]] = {
            "site-clock": self._run_clock,
            "site-localizers": lambda: self._feed(sink),
        }
        alive = [t for t in self._threads if t.is_alive()]
        for name in dead:
            thread = threading.Thread(target=targets[name], name=name, daemon=True)
            thread.start()
            alive.append(thread)
        self._threads = alive
        self.restarts += len(dead)
        return dead

    def stop(self) -> None:
        self._stop.set()
        for t in self._threads:
            t.join(5.0)
        self._threads = []

    def _run_clock(self) -> None:
        period = 1.0 / self.step_hz
        while not self._stop.wait(period):
            try:
                samples = self.site.step(self.clock_ns())
            except Exception:
                log.exception("virtual site step failed")
                continue
            if samples:
                self._samples.put(samples)
        self._samples.put(None)

    def _feed(self, sink: SensorSink) -> None:
        while True:
            samples = self._samples.get()
            if samples is None:
                return
            for sample in samples:
                if isinstance(sample.event, FloorArrival):
                    if self.on_floor is not None:
                        self.on_floor(sample.robot, sample.event)
                    continue
                event: SensorEvent = sample.event
                if isinstance(event, FrameObserved):
                    lag_s = (self.clock_ns() - event.t_ns) * 1e-9
                    if lag_s > self.max_frame_lag_s:
                        self.frames_skipped += 1
                        continue
                try:
                    sink(sample.robot, event)
                except Exception:  # one robot's failure must not stop the others
                    self._failed(sample.robot)

    def _failed(self, robot: str) -> None:
        self.errors += 1
        now = time.monotonic()
        if now - self._error_logged_at >= ERROR_LOG_EVERY_S:
            self._error_logged_at = now
            log.exception(
                "robot %s: an event could not be fed (%d such errors so far)",
                robot,
                self.errors,
                extra={"robot": robot},
            )
