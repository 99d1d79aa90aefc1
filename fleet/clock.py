"""NTP-style clock offset between an agent and the site server, measured over MQTT.

One exchange (RFC 5905, sec. 8): the agent sends a request at `t1` (its clock), the server
receives it at `t2` and answers at `t3` (server clock), the agent receives the answer at `t4`
(its clock). With symmetric paths

    offset = ((t2 - t1) + (t3 - t4)) / 2      (server clock minus agent clock)
    delay  = (t4 - t1) - (t3 - t2)            (round trip, minus the server's hold)

and the true offset lies within `offset +- delay / 2` whatever the asymmetry. Like NTP's
clock filter, `ClockFilter` keeps the last samples and takes the one with the smallest delay
(the least queued, so the most accurate). Pure: every time is an argument, nanoseconds.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass


@dataclass(frozen=True)
class ClockConfig:
    """Clock measurement and what identification tolerates.

    Attributes:
        interval_s: time between exchanges once synchronised, seconds.
        window: samples kept; the one with the smallest delay is used.
        tolerance_s: the largest clock offset that identification tolerates, seconds. LED
            states are announced before a radio command is sent and confirmed after it is
            acknowledged, so a frame time off by less than the radio's one-way latency
            (10 ms at least on the built-in sites, `radio.latency_s`) still falls in the
            right interval; 5 ms leaves a margin. A larger offset is corrected with the
            measurement, but the server warns: the machines' clocks are not synchronised
            (run chrony, docs/fleet.md).
        max_error_s: a measurement whose error bound (delay / 2) exceeds this is not used
            to correct anything (a congested link), seconds.
    """

    interval_s: float = 1.0
    window: int = 8
    tolerance_s: float = 0.005
    max_error_s: float = 0.05

    def __post_init__(self) -> None:
        if self.interval_s <= 0 or self.window < 1 or self.tolerance_s <= 0:
            raise ValueError("ClockConfig: interval_s > 0, window >= 1, tolerance_s > 0")


@dataclass(frozen=True)
class ClockSample:
    """One exchange: agent send `t1`, server receive `t2`, server send `t3`, agent receive
    `t4`, nanoseconds (t1, t4 on the agent's clock; t2, t3 on the server's)."""

    t1: int
    t2: int
    t3: int
    t4: int

    @property
    def offset_ns(self) -> float:
        """Server clock minus agent clock, ns."""
        return ((self.t2 - self.t1) + (self.t3 - self.t4)) / 2.0

    @property
    def delay_ns(self) -> int:
        """Round trip on the network, ns (never negative)."""
        return max(0, (self.t4 - self.t1) - (self.t3 - self.t2))

    @property
    def error_ns(self) -> float:
        """Bound on the offset's error whatever the path asymmetry, ns."""
        return self.delay_ns / 2.0


@dataclass(frozen=True)
class ClockEstimate:
    """The offset in force: server clock = agent clock + `offset_ns` (+- `error_ns`)."""

    offset_ns: int
    error_ns: int
    delay_ns: int
    samples: int

    def within(self, tolerance_s: float) -> bool:
        """False when the clocks certainly disagree by more than `tolerance_s`: the offset
        beyond it by more than its error bound (a congested exchange proves nothing)."""
        return abs(self.offset_ns) - self.error_ns <= tolerance_s * 1e9


class ClockFilter:
    """The best of the last `config.window` samples (smallest delay)."""

    def __init__(self, config: ClockConfig | None = None) -> None:
        self.config = config or ClockConfig()
        self._samples: deque[ClockSample] = deque(maxlen=self.config.window)
        self.rejected = 0

    def add(self, sample: ClockSample) -> ClockEstimate | None:
        """Take one exchange; the estimate in force after it (None: none usable yet).

        A sample with t4 < t1 or t3 < t2 (not one exchange) raises ValueError."""
        if sample.t4 < sample.t1 or sample.t3 < sample.t2:
            raise ValueError(f"clock sample: times out of order: {sample}")
        if sample.error_ns > self.config.max_error_s * 1e9:
            self.rejected += 1
        else:
            self._samples.append(sample)
        return self.estimate

    @property
    def estimate(self) -> ClockEstimate | None:
        if not self._samples:
            return None
        best = min(self._samples, key=lambda s: s.delay_ns)
        return ClockEstimate(
            round(best.offset_ns), round(best.error_ns), best.delay_ns, len(self._samples)
        )
