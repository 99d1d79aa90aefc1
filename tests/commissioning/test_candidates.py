from __future__ import annotations

from commissioning.candidates import doubted_candidates, landmark_id_for_radio, new_radio_candidates
from commissioning.doubt import Doubt
from web.services import Candidate


def test_a_new_radio_takes_its_node_number_when_free_else_the_next_free_id() -> None:
    taken = {100, 101, 205}
    assert landmark_id_for_radio("LM102", taken) == 102 and 102 in taken
    assert landmark_id_for_radio("LM101", taken) == 206  # taken: one above the largest
    assert landmark_id_for_radio("hall light", taken) == 207  # no number
    assert landmark_id_for_radio("LM 99999999999", taken) == 208  # beyond the ID range
    assert landmark_id_for_radio("", set()) == 1


def test_radio_candidates_in_address_order_with_distinct_ids() -> None:
    found = [("0013A200410000C8", "LM200"), ("0013A20041000064", "LM100"), ("0013A2004100FFFF", "")]
    out = new_radio_candidates(found, taken_ids={100, 150})
    assert out == [
        Candidate(151, "0013A20041000064", "new radio 0013A20041000064 (LM100)"),
        Candidate(200, "0013A200410000C8", "new radio 0013A200410000C8 (LM200)"),
        Candidate(201, "0013A2004100FFFF", "new radio 0013A2004100FFFF"),
    ]


def test_doubted_candidates_leave_out_locked_landmarks() -> None:
    doubted = {7: Doubt(7, 80, 2), 3: Doubt(3, 60, 0)}
    assert doubted_candidates(doubted, locked={7}) == [
        Candidate(3, None, "doubted: expected in view 60 times, used 0")
    ]
