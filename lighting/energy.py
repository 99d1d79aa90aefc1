"""What a landmark's two AA cells pay for: the IR LED, the XBee 3 radio awake or asleep, and
each command it receives and answers.

`RadioPower` holds the XBee 3 figures (docs/rf_gateway.md cites them), `RadioSleep` the
cyclic-sleep configuration (SM=4: sleep `SP`, wake, poll the parent, sleep again unless a
message waits; after a message the radio stays awake `ST`, polling every 100 ms, so the
next commands arrive within a poll interval). `EnergyLedger` counts, per landmark, what it
actually did (LED on time, time with the radio awake, messages) and the charge each drew;
`predict_life_days` turns measured duty cycles into days on a fresh pair of cells with the
alkaline discharge curve of `lighting.battery` (the LED current falls with the voltage, so the
curve is integrated, not a straight division).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from lighting.battery import BatteryConfig, cell_voltage, led_current_ma


@dataclass(frozen=True)
class RadioPower:
    """XBee 3 (Zigbee / 802.15.4 / DigiMesh firmware) currents and times at 3.3 V.

    Attributes:
        receive_ma: receiver on (an always-on router listens all the time), mA.
        transmit_ma: transmitting at the default power level, mA.
        sleep_ma: power-down current in cyclic sleep, mA.
        mcu_ma: anything else on the landmark that is always on (LED driver leakage), mA.
        poll_s: awake time of one wake-up with nothing waiting (wake 1-2 ms, send the poll
            request, wait < 10 ms for the parent's acknowledgement), seconds.
        poll_tx_s: of `poll_s`, the time spent transmitting the poll request, seconds.
        message_s: extra awake time of a wake-up that finds a message: receive the remote AT
            command, apply it, transmit the answer and wait for its acknowledgement, with
            `ST` (time before sleep) as short as allowed, seconds.
        message_tx_s: of `message_s`, the time spent transmitting, seconds.
    """

    receive_ma: float = 17.0
    transmit_ma: float = 40.0
    sleep_ma: float = 0.002
    mcu_ma: float = 0.0
    poll_s: float = 0.012
    poll_tx_s: float = 0.001
    message_s: float = 0.030
    message_tx_s: float = 0.003

    def charge_per_message_mah(self) -> float:
        """Charge of receiving and answering one command, mAh (beyond a plain poll)."""
        rx_s = self.message_s - self.message_tx_s
        return (rx_s * self.receive_ma + self.message_tx_s * self.transmit_ma) / 3600.0


@dataclass(frozen=True)
class RadioSleep:
    """Cyclic sleep of a landmark's radio (XBee `SM=4`, end device).

    Attributes:
        period_s: `SP`, time between wake-ups, seconds (XBee 3 Zigbee: 0.32 .. 28 s).
        wake_s: `ST`, how long the radio stays awake after a message, seconds.
        poll_interval_s: its polls while awake (XBee: every 100 ms), seconds.
    """

    period_s: float = 1.0
    wake_s: float = 1.0
    poll_interval_s: float = 0.1

    def __post_init__(self) -> None:
        if not 0.01 <= self.period_s <= 28.0:
            raise ValueError(f"RadioSleep.period_s: 0.01 .. 28 s, got {self.period_s}")
        if self.wake_s < 0 or not 0 < self.poll_interval_s <= self.period_s:
            raise ValueError(
                f"RadioSleep: wake_s >= 0 and 0 < poll_interval_s <= period_s, got "
                f"{self.wake_s}, {self.poll_interval_s}"
            )

    def awake_ma(self, power: RadioPower) -> float:
        """Mean current while awake after a message (a poll every `poll_interval_s`), mA."""
        rx_s = power.poll_s - power.poll_tx_s
        per_poll_mas = rx_s * power.receive_ma + power.poll_tx_s * power.transmit_ma
        return per_poll_mas / self.poll_interval_s


def radio_average_ma(power: RadioPower, sleep: RadioSleep | None) -> float:
    """Mean radio current between messages, mA: the receiver always on (`sleep` None), or
    asleep with one poll per period."""
    if sleep is None:
        return power.receive_ma + power.mcu_ma
    rx_s = power.poll_s - power.poll_tx_s
    per_poll_mas = rx_s * power.receive_ma + power.poll_tx_s * power.transmit_ma
    awake = power.poll_s / sleep.period_s
    return (1.0 - awake) * power.sleep_ma + per_poll_mas / sleep.period_s + power.mcu_ma


def awake_fraction(power: RadioPower, sleep: RadioSleep | None) -> float:
    """Share of the time the radio is awake without messages (1 when it never sleeps)."""
    return 1.0 if sleep is None else min(power.poll_s / sleep.period_s, 1.0)


@dataclass
class LandmarkEnergy:
    """What one landmark did and what it cost (all since the ledger started).

    Attributes:
        time_s: time accounted, seconds.
        led_on_s: time with the LED lit, seconds.
        awake_s: time with the radio awake, seconds.
        tx_s: of `awake_s`, the time transmitting (polls and answers), seconds.
        messages: commands received and answered.
        led_mah, radio_mah: charge drawn by the LED and by the radio, mAh.
        idle_mah: of `radio_mah`, asleep or (awake radios) listening with nothing to do, mAh.
        wake_mah: of `radio_mah`, the cyclic wake-ups that found nothing (poll, wait), mAh.
        message_mah: of `radio_mah`, receiving and answering commands and staying awake
            `ST` after them, mAh.
    """

    time_s: float = 0.0
    led_on_s: float = 0.0
    awake_s: float = 0.0
    tx_s: float = 0.0
    messages: int = 0
    led_mah: float = 0.0
    radio_mah: float = 0.0
    idle_mah: float = 0.0
    wake_mah: float = 0.0
    message_mah: float = 0.0

    @property
    def led_duty(self) -> float:
        return self.led_on_s / self.time_s if self.time_s > 0 else 0.0

    @property
    def radio_ma(self) -> float:
        """Mean radio current over the time accounted (sleep, wake-ups, commands), mA."""
        return self.radio_mah * 3600.0 / self.time_s if self.time_s > 0 else 0.0


@dataclass
class EnergyLedger:
    """Per-landmark accounting of a site's landmarks (the world feeds it).

    Attributes:
        power: the radio's figures.
        sleep: the radios' cyclic sleep, None: always awake.
        landmarks: by ID.
    """

    power: RadioPower = field(default_factory=RadioPower)
    sleep: RadioSleep | None = None
    landmarks: dict[int, LandmarkEnergy] = field(default_factory=dict)

    def radio_ma(self) -> float:
        """Mean radio current between messages, mA."""
        return radio_average_ma(self.power, self.sleep)

    def advance(self, landmark_id: int, dt_s: float, led_ma: float) -> float:
        """Account `dt_s` seconds of one landmark with its LED drawing `led_ma` (0: dark);
        returns the radio charge drawn meanwhile, mAh."""
        e = self.landmarks.setdefault(landmark_id, LandmarkEnergy())
        e.time_s += dt_s
        if led_ma > 0:
            e.led_on_s += dt_s
            e.led_mah += led_ma * dt_s / 3600.0
        awake = dt_s * awake_fraction(self.power, self.sleep)
        e.awake_s += awake
        radio = self.radio_ma() * dt_s / 3600.0
        e.radio_mah += radio
        if self.sleep is None:
            e.idle_mah += radio
        else:
            idle = ((dt_s - awake) * self.power.sleep_ma + dt_s * self.power.mcu_ma) / 3600.0
            e.idle_mah += idle
            e.wake_mah += radio - idle
            e.tx_s += dt_s / self.sleep.period_s * self.power.poll_tx_s
        return radio

    def message(self, landmark_id: int, extra_awake_s: float = 0.0) -> float:
        """Account one command received and answered, and `extra_awake_s` more of staying
        awake after it (`RadioSleep.wake_s`; negative: awake time already counted that a
        shorter `ST` cut off); returns the charge, mAh."""
        e = self.landmarks.setdefault(landmark_id, LandmarkEnergy())
        e.messages += 1
        q = self.power.charge_per_message_mah()
        e.tx_s += self.power.message_tx_s
        if self.sleep is not None:
            e.awake_s += self.power.message_s + extra_awake_s
            q += extra_awake_s * self.sleep.awake_ma(self.power) / 3600.0
            polls = extra_awake_s / self.sleep.poll_interval_s
            e.tx_s += polls * self.power.poll_tx_s
        e.radio_mah += q
        e.message_mah += q
        return q

    def reset(self) -> None:
        """Start counting again (e.g. after a warm-up)."""
        self.landmarks = {}


@dataclass(frozen=True)
class DutyCycle:
    """A landmark's average behaviour over a day (what `predict_life_days` needs).

    Attributes:
        led_duty: share of the time the LED is lit, 0..1.
        messages_per_s: commands received per second, averaged over the day.
        radio_ma: the radio's mean current as measured (`LandmarkEnergy.radio_ma`: sleep,
            wake-ups, commands and the awake time after them as they happened), mA; None:
            modelled from `messages_per_s` (each command keeps the radio awake a whole
            `ST`, no overlap).
    """

    led_duty: float
    messages_per_s: float = 0.0
    radio_ma: float | None = None


def combine_duty(parts: list[tuple[float, DutyCycle]]) -> DutyCycle:
    """The day's duty cycle from (hours, duty) parts, e.g. an 8 h shift and 16 h idle."""
    hours = sum(h for h, _ in parts)
    if hours <= 0:
        raise ValueError("combine_duty: the parts must add up to a positive time")
    measured = [d.radio_ma for _, d in parts]
    radio = (
        None
        if any(m is None for m in measured)
        else sum(h * (d.radio_ma or 0.0) for h, d in parts) / hours
    )
    return DutyCycle(
        sum(h * d.led_duty for h, d in parts) / hours,
        sum(h * d.messages_per_s for h, d in parts) / hours,
        radio,
    )


def predict_life_days(
    duty: DutyCycle,
    *,
    battery: BatteryConfig | None = None,
    power: RadioPower | None = None,
    sleep: RadioSleep | None = None,
    led_scale: float = 1.0,
    charge: float = 1.0,
    steps: int = 200,
) -> float:
    """Days until the cells reach the radio's brown-out at a steady duty cycle.

    Integrates dt = dQ / I(Q) over the discharge curve from `charge` (1 = fresh cells) to
    the brown-out voltage, with I = LED current at the present voltage x `led_duty` (times
    `led_scale`, for an LED current other than the resistor's) + the radio's mean current +
    the messages' charge rate (or the measured `duty.radio_ma` in place of both).

    Returns:
        days (inf when nothing draws any current).
    """
    cfg = battery or BatteryConfig()
    pw = power or RadioPower()
    radio_ma = radio_average_ma(pw, sleep)
    per_msg_mah = pw.charge_per_message_mah()
    if sleep is not None:  # each message keeps it awake up to `wake_s` (no overlap assumed)
        per_msg_mah += sleep.wake_s * sleep.awake_ma(pw) / 3600.0
    msg_ma = duty.messages_per_s * per_msg_mah * 3600.0
    if duty.radio_ma is not None:
        radio_ma, msg_ma = duty.radio_ma, 0.0
    drawn0 = 1.0 - charge
    days = 0.0
    df = (1.0 - drawn0) / steps
    for k in range(steps):
        f = drawn0 + (k + 0.5) * df
        v = cfg.cells * cell_voltage(f)
        if v < cfg.brownout_v:
            break
        i_ma = duty.led_duty * led_scale * led_current_ma(cfg, v) + radio_ma + msg_ma
        if i_ma <= 0:
            return math.inf
        days += df * cfg.capacity_mah / i_ma / 24.0
    return days


def charge_from_voltage(supply_mv: float, battery: BatteryConfig | None = None) -> float:
    """Remaining charge (0..1) of cells reading `supply_mv` at rest (inverts the curve)."""
    cfg = battery or BatteryConfig()
    v_cell = supply_mv / 1000.0 / cfg.cells
    lo, hi = 0.0, 1.0
    for _ in range(40):
        mid = (lo + hi) / 2
        if cell_voltage(mid) > v_cell:
            lo = mid
        else:
            hi = mid
    return 1.0 - (lo + hi) / 2
