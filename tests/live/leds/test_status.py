"""What staff see of the landmarks' energy (live/leds/status.py)."""

from __future__ import annotations

import numpy as np

from live.leds.runtime import LedScheduler
from live.leds.status import EnergyStatus, dim_supply_v


def _status(accounted_s: float, supply_mv: int) -> EnergyStatus:
    scheduler = LedScheduler(
        lambda: ([7], np.zeros((1, 3))), lambda: [], lambda name: 1.0, lambda: None, lambda: 0
    )
    scheduler.accounted_s = accounted_s
    scheduler.lit_s = {7: accounted_s}  # lit all the time so far
    return EnergyStatus(scheduler, lambda: frozenset({7}), lambda lid: supply_mv, 0.5)


def test_a_fresh_start_lit_all_along_does_not_flag_fresh_cells_but_a_settled_duty_does() -> None:
    fresh = _status(120.0, 3130).landmark(7)  # two minutes, every LED lit (identifying)
    assert fresh.duty == 1.0 and fresh.days_to_dim is not None and fresh.days_to_dim < 7.0
    assert not fresh.low
    settled = _status(7200.0, 3130).landmark(7)  # two hours lit: that duty is real
    assert settled.low
    near = _status(120.0, round(dim_supply_v() * 1000) + 50).landmark(7)
    assert near.low  # about to dim: flagged whatever the duty
