"""What is wrong with a robot's ROS 2 inputs, for `/diagnostics`: each problem under a key
(`image`, `camera_info`, `odom`, `transform`, `initialpose`), with a level, the sentence
that says what was wrong, how often it happened and when last (thread-safe: the DDS threads
report, the diagnostics publisher reads).
"""

from __future__ import annotations

import logging
import threading
import time
from dataclasses import dataclass
from typing import Literal

log = logging.getLogger(__name__)

Level = Literal["ok", "warn", "error"]
LEVEL_BYTE: dict[Level, int] = {"ok": 0, "warn": 1, "error": 2}
"""diagnostic_msgs/DiagnosticStatus levels (OK, WARN, ERROR)."""


@dataclass(frozen=True)
class Problem:
    key: str
    level: Level
    message: str
    count: int
    last_mono_ns: int


class Health:
    """The open problems of one robot's inputs.

    Args:
        name: the robot's name (in the log lines).
        stale_s: a problem not reported again for this long is closed.
    """

    def __init__(self, name: str, stale_s: float = 5.0) -> None:
        self.name = name
        self.stale_ns = round(stale_s * 1e9)
        self._problems: dict[str, Problem] = {}
        self._lock = threading.Lock()

    def report(self, key: str, level: Level, message: str) -> None:
        """Record a problem (logged at its first occurrence and when its message changes)."""
        now = time.monotonic_ns()
        with self._lock:
            old = self._problems.get(key)
            count = 1 if old is None else old.count + 1
            self._problems[key] = Problem(key, level, message, count, now)
        if old is None or old.message != message:
            log.warning("%s: %s: %s", self.name, key, message)

    def clear(self, key: str) -> None:
        with self._lock:
            self._problems.pop(key, None)

    def problems(self) -> list[Problem]:
        """Open problems, worst first (stale ones closed)."""
        now = time.monotonic_ns()
        with self._lock:
            for k in [k for k, p in self._problems.items() if now - p.last_mono_ns > self.stale_ns]:
                del self._problems[k]
            out = list(self._problems.values())
        return sorted(out, key=lambda p: (-LEVEL_BYTE[p.level], p.key))

    def problem(self, key: str) -> Problem | None:
        with self._lock:
            return self._problems.get(key)
