from __future__ import annotations

import itertools

import pytest

from survey.blinks import BlinkConfig, blink_schedule, blink_schedule_in_view

NS = 1_000_000_000


def test_one_landmark_dark_at_a_time_round_robin() -> None:
    cfg = BlinkConfig(frame_period_s=0.04, dark_frames=3, lit_frames=2, radio_latency_s=0.01)
    ids = [5, 6, 7]
    changes = blink_schedule(ids, NS, 3 * NS, cfg)
    dark = [c for c in changes if not c.all_lit]
    lit = [c for c in changes if c.all_lit]
    assert len(dark) == len(lit)
    assert [sorted(set(ids) - c.lit) for c in dark[:4]] == [[5], [6], [7], [5]]
    assert changes[-1].all_lit
    slot = round(cfg.slot_s * NS)
    assert [c.t_ns for c in dark[:3]] == [NS, NS + slot, NS + 2 * slot]
    # dark for dark_frames frame periods plus the radio's latency
    assert dark[0].t_ns + round((3 * 0.04 + 0.01) * NS) == lit[0].t_ns
    assert all(a.t_ns < b.t_ns for a, b in itertools.pairwise(changes))


def test_bad_configuration_and_duplicate_ids_are_refused() -> None:
    with pytest.raises(ValueError, match="dark_frames"):
        BlinkConfig(dark_frames=1)
    with pytest.raises(ValueError, match="unique"):
        blink_schedule([1, 1], 0, NS, BlinkConfig())
    assert blink_schedule([], 0, NS, BlinkConfig())[0].all_lit


def test_windows_aimed_at_the_landmarks_in_view_least_blinked_first() -> None:
    cfg = BlinkConfig(frame_period_s=0.04, dark_frames=3, lit_frames=2, radio_latency_s=0.01)
    ids = [5, 6, 7, 8]
    slot = round(cfg.slot_s * NS)
    # 7 and 8 in view during the first six slots, none afterwards
    changes = blink_schedule_in_view(
        ids, 0, 12 * slot, cfg, lambda t: [7, 8] if t < 6 * slot else [], sweep_every=3
    )
    dark = [sorted(set(ids) - c.lit)[0] for c in changes if not c.all_lit]
    # every third slot, and every slot with none in view, sweeps in turn what was never in
    # view (landmarks with no position get named too)
    assert dark == [5, 7, 8, 6, 7, 8, 5, 6, 5, 6, 5, 6]
