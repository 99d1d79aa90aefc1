"""The agent's clocks: its localizer runs on its own monotonic clock; what it sends and
receives is stamped on the site server's wall clock, Unix ns (`fleet.payloads`), converted
with the offset measured over MQTT (`fleet.clock`).

`skew_ns` makes this agent's wall clock wrong on purpose (tests and demos of the clock
correction: an agent whose clock is not synchronised by chrony).
"""

from __future__ import annotations

import time


class TimeBase:
    """Conversions between the agent's monotonic clock and the site server's wall clock.

    Attributes:
        offset_ns: server wall clock minus this agent's wall clock, as last measured (0
            before the first measurement: chrony-synchronised machines agree to ~1 ms).
        skew_ns: added to this machine's wall clock (a simulated unsynchronised clock).
    """

    def __init__(self, skew_ns: int = 0) -> None:
        self.offset_ns = 0
        self.skew_ns = skew_ns

    @staticmethod
    def mono_ns() -> int:
        return time.monotonic_ns()

    def wall_ns(self) -> int:
        """This agent's wall clock (what NTP-style exchanges stamp t1, t4 with)."""
        return time.time_ns() + self.skew_ns

    def _wall_minus_mono(self) -> int:
        return self.wall_ns() - time.monotonic_ns()

    def site_now_ns(self) -> int:
        """Now on the site server's wall clock."""
        return self.wall_ns() + self.offset_ns

    def site_from_mono(self, t_mono_ns: int) -> int:
        return t_mono_ns + self._wall_minus_mono() + self.offset_ns

    def mono_from_site(self, t_site_ns: int) -> int:
        return t_site_ns - self.offset_ns - self._wall_minus_mono()
