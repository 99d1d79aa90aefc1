"""`BadKeyThrottle`: a token bucket of failed key checks per client address.

Every request or WebSocket with a missing-from-cache key that turns out bad spends one token
of its address's bucket (`burst` tokens, refilled at `rate_per_s`); an address with an empty
bucket gets 429 (WebSocket: close 1008) before its key is even looked up, until the bucket
refills. Valid keys already in the key cache pass regardless, so one misconfigured client on
a shared address does not lock out the others for longer than a refill.
"""

from __future__ import annotations

import logging
import threading
import time
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass

log = logging.getLogger(__name__)
LOG_EVERY_S = 10.0
"""Bad keys are logged as one line per burst: at most one line in this time, with counts
(the access log leaves out 401 and 429 answers, `server.logs.QuietRefusals`)."""


@dataclass(frozen=True)
class ThrottleConfig:
    """Attributes:
    burst: bad keys an address may send before it is throttled.
    rate_per_s: bad keys per second it may send after that.
    max_addresses: addresses remembered (the oldest forgotten first).
    """

    burst: int = 10
    rate_per_s: float = 1.0
    max_addresses: int = 10_000


class BadKeyThrottle:
    """Per-address budget of bad keys (thread-safe)."""

    def __init__(
        self, config: ThrottleConfig | None = None, clock: Callable[[], float] = time.monotonic
    ) -> None:
        self.config = config or ThrottleConfig()
        self.clock = clock
        self.throttled = 0
        self._buckets: OrderedDict[str, tuple[float, float]] = OrderedDict()  # tokens, at
        self._lock = threading.Lock()
        self.bad = 0
        self._unlogged = 0
        self._throttled_logged = 0
        self._logged_at: float | None = None

    def _tokens(self, address: str, now: float) -> float:
        tokens, at = self._buckets.get(address, (float(self.config.burst), now))
        return min(float(self.config.burst), tokens + (now - at) * self.config.rate_per_s)

    def retry_after_s(self, address: str) -> float:
        """0 when `address` may try a key now, else seconds until it may."""
        now = self.clock()
        with self._lock:
            tokens = self._tokens(address, now)
        if tokens >= 1.0:
            return 0.0
        self.throttled += 1
        return (1.0 - tokens) / self.config.rate_per_s

    def failed(self, address: str) -> None:
        """Spend one token of `address` for a bad key."""
        now = self.clock()
        with self._lock:
            self._buckets[address] = (max(0.0, self._tokens(address, now) - 1.0), now)
            self._buckets.move_to_end(address)
            while len(self._buckets) > self.config.max_addresses:
                self._buckets.popitem(last=False)
            self.bad += 1
            self._unlogged += 1
            due = self._logged_at is None or now - self._logged_at >= LOG_EVERY_S
            if due:
                count, self._unlogged, self._logged_at = self._unlogged, 0, now
                throttled, self._throttled_logged = (
                    self.throttled - self._throttled_logged,
                    self.throttled,
                )
        if due:
            log.warning(
                "bad API keys: %d since the last such line (%d throttled), the latest from %s",
                count,
                throttled,
                address,
            )
