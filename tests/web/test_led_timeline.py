from __future__ import annotations

import pytest

from localizer.events import LedsChanged
from web.led_timeline import LedsAt, LedTimeline

S = 1_000_000_000
ALL = frozenset({1, 2, 3, 4})


def darken_probe() -> LedTimeline:
    """All lit at 0 s; LED 2 darkened (announced 10.0 s, confirmed 10.05 s), relit (announced
    10.2 s, confirmed 10.25 s)."""
    tl = LedTimeline()
    tl.add(LedsChanged(0, all_lit=True), ALL)
    tl.add(LedsChanged(10 * S, all_lit=True, changing=frozenset({2})), ALL)
    tl.add(LedsChanged(10_050_000_000, frozenset({1, 3, 4})), ALL)
    tl.add(LedsChanged(10_200_000_000, frozenset({1, 3, 4}), changing=frozenset({2})), ALL)
    tl.add(LedsChanged(10_250_000_000, all_lit=True), ALL)
    return tl


def test_the_leds_at_a_frames_time_not_now() -> None:
    tl = darken_probe()
    assert tl.at(-1, quiet_s=0.5) is None  # before anything known
    assert tl.at(5 * S, quiet_s=0.5) == LedsAt(ALL, frozenset())
    # while the command is in flight: unsure; dark once confirmed, unsure all the while
    assert tl.at(10_010_000_000, quiet_s=0.5) == LedsAt(ALL, frozenset({2}))
    assert tl.at(10_100_000_000, quiet_s=0.5) == LedsAt(frozenset({1, 3, 4}), frozenset({2}))
    # lit again, but switched within the quiet time before the frame
    assert tl.at(10_700_000_000, quiet_s=0.5) == LedsAt(ALL, frozenset({2}))
    assert tl.at(10_760_000_000, quiet_s=0.5) == LedsAt(ALL, frozenset())
    assert tl.at(10_260_000_000, quiet_s=0.0) == LedsAt(ALL, frozenset())


def test_a_still_changing_state_is_unsure_however_old() -> None:
    tl = LedTimeline()
    tl.add(LedsChanged(0, frozenset({1}), changing=frozenset({3})), ALL)
    assert tl.at(60 * S, quiet_s=0.5) == LedsAt(frozenset({1}), frozenset({3}))


def test_old_states_are_dropped_but_the_one_in_force_is_kept() -> None:
    tl = LedTimeline(keep_s=5.0)
    tl.add(LedsChanged(0, all_lit=True), ALL)
    tl.add(LedsChanged(1 * S, frozenset({1})), ALL)
    tl.add(LedsChanged(10 * S, frozenset({1, 2})), ALL)
    assert tl.at(0, quiet_s=0.5) is None  # dropped
    assert tl.at(4 * S, quiet_s=0.5) == LedsAt(frozenset({1}), frozenset())
    assert tl.at(10 * S, quiet_s=0.5) == LedsAt(frozenset({1, 2}), frozenset({2}))
    # a stale (older) state is ignored; one as old as the newest is taken
    tl.add(LedsChanged(9 * S, frozenset({4})), ALL)
    assert tl.at(11 * S, quiet_s=0.0) == LedsAt(frozenset({1, 2}), frozenset())
    tl.add(LedsChanged(10 * S, frozenset({3})), ALL)
    assert tl.at(11 * S, quiet_s=0.0) == LedsAt(frozenset({3}), frozenset())
    with pytest.raises(ValueError, match="keep_s"):
        LedTimeline(keep_s=0.0)
