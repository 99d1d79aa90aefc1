"""When the sleeping landmarks should stay awake: while a robot identifies (pure logic).

A robot without a pose identifies by switching one landmark at a time and watching which
spot changes; with radios in cyclic sleep each of those commands waits up to a sleep period
(`SP`) for the landmark to wake, so identification crawls (tens of probes, each up to `SP`).
While any robot identifies (or is lost, or has no pose at all) the landmarks' time awake
after a message (`ST`) is raised to `identify_wake_s`: after its next command each
landmark polls its parent every 100 ms for that long (every further command restarts the
timer), so probes land within a poll interval. Once every robot has held a pose for
`relax_after_s`, `ST` goes back to `normal_wake_s` and the landmarks sleep again. A window
the gateway already opened (its start-up broadcast, `GatewayConfig.start_awake_s`) starts
open (`opened=True`): the first robots identifying after a restart cost no `ST` commands.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class WakeWindowConfig:
    """Tuning of the wake window.

    Attributes:
        normal_wake_s: `ST` in normal operation, seconds (XBee `ST`, the landmarks' own).
        identify_wake_s: `ST` while a robot identifies, seconds (each landmark then stays
            awake this long after its last command: a bound on what a forgotten window
            costs, about 2.3 mA x this per landmark).
        relax_after_s: every robot must have had a pose this long before `ST` goes back,
            seconds (a robot that just fixed may lose it again at once).
    """

    normal_wake_s: float = 1.0
    identify_wake_s: float = 30.0
    relax_after_s: float = 5.0

    def __post_init__(self) -> None:
        if not 0 < self.normal_wake_s <= self.identify_wake_s or self.relax_after_s < 0:
            raise ValueError(
                "WakeWindowConfig: 0 < normal_wake_s <= identify_wake_s and relax_after_s >= "
                f"0, got {self.normal_wake_s}, {self.identify_wake_s}, {self.relax_after_s}"
            )


class WakeWindow:
    """Decides when to raise and lower the landmarks' `ST` (no clock: times are passed)."""

    def __init__(self, config: WakeWindowConfig | None = None, *, opened: bool = False) -> None:
        self.config = config or WakeWindowConfig()
        self.open = opened
        self._posed_since_s: float | None = None

    def update(self, t_s: float, *, identifying: bool) -> float | None:
        """The `ST` to send to every landmark now, or None (nothing to change).

        Args:
            t_s: now, seconds (any monotonic clock).
            identifying: some robot identifies, is lost or has no pose.
        """
        cfg = self.config
        if identifying:
            self._posed_since_s = None
            if not self.open:
                self.open = True
                return cfg.identify_wake_s
            return None
        if self._posed_since_s is None:
            self._posed_since_s = t_s
        if self.open and t_s - self._posed_since_s >= cfg.relax_after_s:
            self.open = False
            return cfg.normal_wake_s
        return None
