"""`SimSource`: the virtual site (`sim.live.LiveSite`) as a `FrameSource` for its robots.

One thread steps the site at `step_hz` on the site clock (frames are rendered with the LEDs
lit at the call, so a short period keeps a frame's picture true to its timestamp); another
feeds the samples to the sink, skipping frames older than `max_frame_lag_s` when their turn
comes (odometry never is), so a slow localizer falls behind by frames, not by time.
"""

from __future__ import annotations

import logging
import queue
import threading
from collections.abc import Callable, Sequence

from localizer.events import FrameObserved
from sensors.sources import SensorEvent, SensorSink
from sim.live import LiveSite, SensorSample

log = logging.getLogger(__name__)


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
        site: LiveSite,
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
        self._stop = threading.Event()
        self._samples: queue.SimpleQueue[list[SensorSample] | None] = queue.SimpleQueue()
        self._threads: list[threading.Thread] = []

    @property
    def robots(self) -> Sequence[str]:
        return list(self.site.robot_names)

    def start(self, sink: SensorSink) -> None:
        self._threads = [
            threading.Thread(target=self._run_clock, name="site-clock", daemon=True),
            threading.Thread(target=self._feed, args=(sink,), name="site-localizers", daemon=True),
        ]
        for t in self._threads:
            t.start()

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
                event: SensorEvent = sample.event
                if isinstance(event, FrameObserved):
                    lag_s = (self.clock_ns() - event.t_ns) * 1e-9
                    if lag_s > self.max_frame_lag_s:
                        self.frames_skipped += 1
                        continue
                sink(sample.robot, event)
