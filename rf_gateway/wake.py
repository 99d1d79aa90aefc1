"""When to send to a sleeping landmark: its wake-ups, learnt from its answers.

A landmark in cyclic sleep receives a command only when it polls its parent: at its next
wake-up (every `SP`), or within a poll interval while it stays awake after a message (`ST`).
A command sent long before the wake-up holds one of the coordinator's few in-flight slots
(`GatewayConfig.max_in_flight`) for nothing, so the gateway waits until just before the
landmark's next wake-up when it knows it: an answer that took longer than an awake round
trip came right after a wake-up, which fixes the landmark's phase; any answer means it is
awake for `ST` more. Unknown landmarks are sent to at once.
"""

from __future__ import annotations

import math

from rf_gateway.config import SleepConfig


class WakeTracker:
    """Predicted wake-ups of sleeping landmarks (times on one monotonic clock, seconds)."""

    def __init__(self, sleep: SleepConfig | None) -> None:
        self.sleep = sleep
        self._phase: dict[int, float] = {}
        self._awake_until: dict[int, float] = {}
        self._wake_s: dict[int, float] = {}

    def set_wake_s(self, landmark_id: int, wake_s: float, now_s: float) -> None:
        """The landmark's `ST` was set to `wake_s` by a command answered at `now_s`."""
        self._wake_s[landmark_id] = wake_s
        self._awake_until[landmark_id] = now_s + wake_s

    def send_delay_s(self, landmark_id: int, now_s: float) -> float:
        """How long to wait before sending a command to the landmark (0: send now)."""
        sl = self.sleep
        if sl is None or now_s < self._awake_until.get(landmark_id, -math.inf) - sl.air_s:
            return 0.0
        phase = self._phase.get(landmark_id)
        if phase is None:
            return 0.0
        ahead = sl.lead_s + sl.air_s
        next_wake = phase + math.ceil((now_s + ahead - phase) / sl.period_s) * sl.period_s
        return max(next_wake - ahead - now_s, 0.0)

    def answered(self, landmark_id: int, sent_s: float, answered_s: float) -> None:
        """A command sent at `sent_s` was answered at `answered_s`."""
        sl = self.sleep
        if sl is None:
            return
        if answered_s - sent_s > sl.poll_interval_s + 2 * sl.air_s:
            self._phase[landmark_id] = (answered_s - sl.air_s / 2) % sl.period_s
        self._awake_until[landmark_id] = answered_s + self._wake_s.get(landmark_id, sl.wake_s)

    def forget(self, landmark_id: int) -> None:
        """No answer (timeout): the landmark's timing is no longer known."""
        self._phase.pop(landmark_id, None)
        self._awake_until.pop(landmark_id, None)
