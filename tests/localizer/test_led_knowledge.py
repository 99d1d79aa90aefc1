"""What the localizer knows of the LEDs (`led_knowledge.LedKnowledge`)."""

from __future__ import annotations

import numpy as np

from localizer.events import LedRequest, LedsChanged
from localizer.identification_config import IdentificationConfig
from localizer.landmark_map import LandmarkMap
from localizer.led_knowledge import LedKnowledge

MAP = LandmarkMap(np.array([7, 3, 5]), np.array([[0.0, 0, 2.5], [1.2, 0, 2.5], [0, 1.2, 2.5]]))
CFG = IdentificationConfig(led_settle_frames=1, led_settle_s=0.02)
MS = 1_000_000


def test_all_lit_until_told_and_unknown_while_a_switch_is_in_flight() -> None:
    leds = LedKnowledge(MAP)
    assert leds.lit is None and leds.known_lit() == {3, 5, 7}  # nothing reported: all lit
    leds.reported(LedsChanged(10 * MS, lit=frozenset({3}), changing=frozenset({5})))
    assert leds.known_lit() is None  # 5 is being switched: the state is unknown
    np.testing.assert_array_equal(leds.lit_rows(), [1])  # only 3 surely lit (map row 1)
    leds.reported(LedsChanged(20 * MS, lit=frozenset({3, 5})))
    assert leds.known_lit() == {3, 5}
    np.testing.assert_array_equal(leds.lit_rows(), [1, 2])
    assert leds.lit_rows() is leds.lit_rows()  # remembered while the state stays


def test_frames_right_after_a_change_are_no_evidence() -> None:
    leds = LedKnowledge(MAP)
    assert leds.lit_for_evidence(5 * MS, CFG) == {3, 5, 7}  # no change seen yet
    leds.reported(LedsChanged(10 * MS, lit=frozenset({7})))
    assert leds.lit_for_evidence(40 * MS, CFG) is None  # the first frame after the change
    assert leds.lit_for_evidence(25 * MS, CFG) is None  # within led_settle_s of it
    assert leds.lit_for_evidence(31 * MS, CFG) == {7}
    leds.reported(LedsChanged(50 * MS, lit=frozenset({7})))  # the same state: no change
    assert leds.lit_for_evidence(51 * MS, CFG) == {7}


def test_a_request_is_awaited_until_confirmed_or_timed_out() -> None:
    leds = LedKnowledge(MAP)
    leds.want_all = True
    assert leds.all_lit_request(0) is None  # all lit already: nothing to ask
    leds.reported(LedsChanged(0, lit=frozenset({3})))
    leds.want_all = True
    assert leds.all_lit_request(100 * MS) == LedRequest(all_lit=True)
    assert leds.all_lit_request(110 * MS) is None  # asked once
    assert leds.awaiting(500 * MS, 0.5) and not leds.awaiting(700 * MS, 0.5)
    leds.reported(LedsChanged(200 * MS, all_lit=True))
    assert not leds.awaiting(300 * MS, 0.5)
