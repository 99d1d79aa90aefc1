"""A landmark's battery: two AA alkaline cells in series feeding the radio and the IR LED.

The open-circuit cell voltage falls with the charge drawn (a tabulated alkaline discharge
curve); under load the internal resistance sags it further. The LED hangs on the supply
through a series resistor, so its current, and its brightness, falls as the voltage falls, and
stops once the supply no longer clears the LED's forward voltage. Below the radio's brown-out
voltage the landmark no longer answers.
"""

from __future__ import annotations

import bisect
from dataclasses import dataclass

# Alkaline AA: fraction of capacity drawn -> open-circuit voltage of one cell, volts.
_DRAWN_FRACTION = (0.0, 0.05, 0.2, 0.5, 0.8, 0.9, 0.97, 1.0)
_CELL_VOLTS = (1.58, 1.48, 1.38, 1.27, 1.16, 1.09, 1.0, 0.8)


@dataclass(frozen=True)
class BatteryConfig:
    """Cells, loads and the LED circuit of one landmark.

    Attributes:
        capacity_mah: charge of a fresh cell, mAh (both cells in series carry the same).
        cells: cells in series.
        internal_resistance_ohm: per cell.
        idle_current_ma: radio and microcontroller, mA.
        led_forward_v: the IR LED's forward voltage, volts.
        led_resistor_ohm: series resistor of the LED.
        brownout_v: below this supply voltage the radio stops answering, volts.
    """

    capacity_mah: float = 2500.0
    cells: int = 2
    internal_resistance_ohm: float = 0.15
    idle_current_ma: float = 1.0
    led_forward_v: float = 1.35
    led_resistor_ohm: float = 33.0
    brownout_v: float = 2.1

    @property
    def nominal_led_current_ma(self) -> float:
        """LED current with fresh cells, mA (the current of brightness 1.0)."""
        return led_current_ma(self, self.cells * float(_CELL_VOLTS[0]))


def cell_voltage(drawn_fraction: float) -> float:
    """Open-circuit voltage of one alkaline cell after drawing `drawn_fraction` of it, V.

    Linear between the points of the tabulated discharge curve (a plain-Python `np.interp`:
    this runs for every landmark at every frame).
    """
    f = min(max(drawn_fraction, 0.0), 1.0)
    i = min(max(bisect.bisect_right(_DRAWN_FRACTION, f), 1), len(_DRAWN_FRACTION) - 1)
    f0, f1 = _DRAWN_FRACTION[i - 1], _DRAWN_FRACTION[i]
    v0, v1 = _CELL_VOLTS[i - 1], _CELL_VOLTS[i]
    return v0 + (v1 - v0) * (f - f0) / (f1 - f0)


def led_current_ma(config: BatteryConfig, supply_v: float) -> float:
    """LED current through its series resistor at a supply voltage, mA (0 below forward V)."""
    return max(supply_v - config.led_forward_v, 0.0) / config.led_resistor_ohm * 1000.0


class Battery:
    """The state of one landmark's cells.

    Args:
        config: the circuit.
        charge: remaining fraction of capacity, 0..1 (1 = fresh cells).
    """

    def __init__(self, config: BatteryConfig | None = None, *, charge: float = 1.0) -> None:
        if not 0.0 <= charge <= 1.0:
            raise ValueError(f"battery charge must be in [0, 1], got {charge!r}")
        self.config = config or BatteryConfig()
        self.drawn_mah = (1.0 - charge) * self.config.capacity_mah
        self._ocv_cache = (-1.0, 0.0)  # (drawn_mah, open-circuit volts)

    @property
    def drawn_fraction(self) -> float:
        return min(self.drawn_mah / self.config.capacity_mah, 1.0)

    def open_circuit_v(self) -> float:
        """Supply voltage with no load, volts."""
        if self._ocv_cache[0] != self.drawn_mah:
            self._ocv_cache = (
                self.drawn_mah,
                self.config.cells * cell_voltage(self.drawn_fraction),
            )
        return self._ocv_cache[1]

    def supply_v(self, led_on: bool) -> float:
        """Supply voltage under the present load, volts (LED current solved with the sag)."""
        cfg = self.config
        v_oc = self.open_circuit_v()
        r_int = cfg.cells * cfg.internal_resistance_ohm
        idle_a = cfg.idle_current_ma / 1000.0
        if not led_on:
            return v_oc - idle_a * r_int
        # v = v_oc - r_int * (idle + (v - vf) / R)  ->  solve for v (LED conducting)
        v = (v_oc - r_int * idle_a + r_int * cfg.led_forward_v / cfg.led_resistor_ohm) / (
            1.0 + r_int / cfg.led_resistor_ohm
        )
        return v if v > cfg.led_forward_v else v_oc - idle_a * r_int

    def current_ma(self, led_on: bool) -> float:
        """Total current drawn, mA (nothing once browned out)."""
        if not self.alive:
            return 0.0
        led = led_current_ma(self.config, self.supply_v(True)) if led_on else 0.0
        return self.config.idle_current_ma + led

    def led_brightness(self) -> float:
        """Brightness of the lit LED relative to fresh cells (0 when dead), 0..~1."""
        if not self.alive:
            return 0.0
        return led_current_ma(self.config, self.supply_v(True)) / self.config.nominal_led_current_ma

    @property
    def alive(self) -> bool:
        """The radio and microcontroller still run (supply above brown-out)."""
        return self.open_circuit_v() >= self.config.brownout_v

    def led_ma(self, led_on: bool) -> float:
        """The LED's current now, mA (0 when dark or browned out)."""
        if not led_on or not self.alive:
            return 0.0
        return led_current_ma(self.config, self.supply_v(True))

    def draw(self, mah: float) -> None:
        """Take `mah` of charge (an energy model's account of what the landmark did; a
        negative amount returns charge taken too early, e.g. awake time cut short)."""
        self.drawn_mah = min(max(self.drawn_mah + mah, 0.0), self.config.capacity_mah)

    def advance(self, dt_s: float, led_on: bool) -> None:
        """Draw the load's charge for `dt_s` seconds (LED and `idle_current_ma`)."""
        if dt_s > 0:
            self.draw(self.current_ma(led_on) * dt_s / 3600.0)
