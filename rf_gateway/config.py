"""Gateway tuning and counters."""

from __future__ import annotations

from dataclasses import dataclass, field

from rf_gateway.battery import BatteryMonitorConfig


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
        sleep: the landmarks' radios sleep in cycles (None: always awake): commands wait
            for a landmark's predicted wake-up before taking an in-flight slot.
        start_awake_s: with sleeping landmarks and a transport that broadcasts
            (`BroadcastTransport`), the start-up sweep is two broadcasts instead of one
            command per landmark through the few in-flight slots, each waiting for its
            wake-up: LED on, then (`SleepConfig.broadcast_wait_s` later, every landmark
            having polled once) `ST` = this, seconds (the wake window of the robots'
            identification). The LEDs are published lit at once and read back one by one
            meanwhile (`Gateway._verify_believed`). None: no broadcast.
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
    battery: BatteryMonitorConfig = field(default_factory=BatteryMonitorConfig)
    sleep: SleepConfig | None = None
    start_awake_s: float | None = None


@dataclass(frozen=True)
class SleepConfig:
    """The landmarks' radios sleep in cycles (XBee `SM=4`, end devices, `SP` = `period_s`):
    a command waits at the parent until the landmark next polls, up to one period.

    Attributes:
        period_s: the sleep period `SP`, seconds (XBee 3 Zigbee: 0.32 .. 28 s; the parent
            buffers a message for up to 30 s).
        wake_s: `ST`, how long a landmark stays awake after a message (polling its parent
            every `poll_interval_s`), seconds.
        poll_interval_s: its polls while awake (XBee: 100 ms), seconds.
        air_s: a command's time on the air and back once the landmark polls, seconds.
        lead_s: a command to a landmark whose wake-up time is known is sent this long before
            it (clock drift of the sleep timer, the host's own latency), seconds.
        awake_timeout_s: answer timeout of an awake radio, seconds (the transport's).
    """

    period_s: float
    wake_s: float = 1.0
    poll_interval_s: float = 0.1
    air_s: float = 0.05
    lead_s: float = 0.08
    awake_timeout_s: float = 1.0

    def __post_init__(self) -> None:
        if not 0.32 <= self.period_s <= 28.0:
            raise ValueError(f"SleepConfig.period_s: 0.32 .. 28 s (XBee SP), got {self.period_s}")
        if self.wake_s < 0 or self.poll_interval_s <= 0 or self.lead_s < 0:
            raise ValueError(
                "SleepConfig: wake_s >= 0, poll_interval_s > 0, lead_s >= 0, got "
                f"{self.wake_s}, {self.poll_interval_s}, {self.lead_s}"
            )

    @property
    def command_timeout_s(self) -> float:
        """How long to wait for a sleeping landmark's answer: one period plus the awake
        timeout (digi-xbee's per-remote sync-ops timeout must be at least this)."""
        return self.period_s + self.awake_timeout_s

    @property
    def broadcast_wait_s(self) -> float:
        """How long until every landmark took a broadcast: each polls once a period (the
        parent buffers it for 1.2 periods), plus an air time."""
        return self.period_s + self.air_s


@dataclass
class GatewayStats:
    """Counters for the metrics page."""

    commands: int = 0
    retries: int = 0
    failures: int = 0
    skipped: int = 0
    published: int = 0
    broadcasts: int = 0
    broadcast_missed: int = 0
