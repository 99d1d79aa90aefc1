"""Gateway tuning and counters."""

from __future__ import annotations

from dataclasses import dataclass, field

from rf_gateway.battery import BatteryConfig


@dataclass(frozen=True)
class GatewayConfig:
    """Gateway tuning.

    Attributes:
        max_in_flight: radio commands on the air at once.
        max_waiting: commands allowed to wait for a slot (more raise QueueFullError).
        max_tries: sends per command before the landmark is declared unreachable.
        unreachable_tries: sends per command to a landmark already marked unreachable (one
            probe, so that a dead landmark does not slow every identification step).
        retry_backoff_s: wait before the first retry; doubles at each further retry.
        command_timeout_s: gateway-side safety timeout per command (transports have their
            own, shorter, timeouts).
        skip_confirmed: do not resend a level the landmark already confirmed.
        light_all_on_start: `start()` lights every LED in the background (the normal tracking
            state), so that the LED state is known and published from the start.
        discover_rounds: node discoveries per `discover` (their answers merged: a radio's
            answer lost on the air, or colliding with another's, is caught by the next).
        blink_count, blink_period_s: `blink` toggles the LED this many times, one period each.
        subscriber_queue: events buffered per subscriber.
        battery: battery monitoring settings.
    """

    max_in_flight: int = 4
    max_waiting: int = 512
    max_tries: int = 3
    unreachable_tries: int = 1
    retry_backoff_s: float = 0.05
    command_timeout_s: float = 10.0
    skip_confirmed: bool = True
    light_all_on_start: bool = True
    discover_rounds: int = 2
    blink_count: int = 3
    blink_period_s: float = 0.4
    subscriber_queue: int = 256
    battery: BatteryConfig = field(default_factory=BatteryConfig)


@dataclass
class GatewayStats:
    """Counters for the metrics page."""

    commands: int = 0
    retries: int = 0
    failures: int = 0
    skipped: int = 0
    published: int = 0
