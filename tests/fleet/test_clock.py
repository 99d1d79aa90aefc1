"""NTP-style clock offset (fleet/clock.py)."""

from __future__ import annotations

import numpy as np
import pytest

from fleet.clock import ClockConfig, ClockFilter, ClockSample

MS = 1_000_000


def exchange(
    offset_ns: int, out_ns: int, back_ns: int, hold_ns: int = 0, t1: int = 10**12
) -> ClockSample:
    """An exchange with a true offset (server minus agent) and one-way delays."""
    t2 = t1 + out_ns + offset_ns
    t3 = t2 + hold_ns
    t4 = t3 - offset_ns + back_ns
    return ClockSample(t1, t2, t3, t4)


def test_symmetric_paths_give_the_offset_exactly() -> None:
    s = exchange(-200 * MS, 3 * MS, 3 * MS, hold_ns=MS)
    assert s.offset_ns == -200 * MS
    assert s.delay_ns == 6 * MS and s.error_ns == 3 * MS


def test_asymmetry_errs_by_half_the_difference_within_the_bound() -> None:
    s = exchange(50 * MS, 1 * MS, 9 * MS)
    assert s.offset_ns == pytest.approx(50 * MS - 4 * MS)
    assert abs(s.offset_ns - 50 * MS) <= s.error_ns


def test_the_filter_takes_the_least_delayed_sample() -> None:
    rng = np.random.default_rng(3)
    f = ClockFilter(ClockConfig(window=8))
    true = 7 * MS
    for _ in range(8):
        out, back = rng.uniform(0.2, 20, 2) * MS
        f.add(exchange(true, int(out), int(back)))
    f.add(exchange(true, MS // 10, MS // 10))
    est = f.estimate
    assert est is not None and est.delay_ns == MS // 5
    assert abs(est.offset_ns - true) <= est.error_ns <= MS // 10
    assert est.within(0.008) and not est.within(0.0068)


def test_congested_samples_are_not_used_and_bad_ones_refused() -> None:
    f = ClockFilter(ClockConfig(max_error_s=0.05))
    assert f.add(exchange(0, 80 * MS, 80 * MS)) is None and f.rejected == 1
    with pytest.raises(ValueError, match="out of order"):
        f.add(ClockSample(10, 5, 4, 20))
