"""Identification (Sec. III-A) from LED switches and spots: the paper's one-lit sweep and
darkening one landmark of a lit ceiling at a time."""

from __future__ import annotations

import numpy as np
import pytest

from localizer.events import LedRequest
from localizer.identification import IdentificationConfig, Identifier

MS = 1_000_000
STRAY = (100.0, 100.0)


def _ident(**kw: object) -> Identifier:
    """The paper's sweep (one LED lit at a time) unless `probe` is given."""
    kw.setdefault("probe", "light_one")
    return Identifier(IdentificationConfig(**kw), [1, 2, 3], motion_px=lambda a, b: 0.0)  # type: ignore[arg-type]


def _obs(ident: Identifier, t_ms: int, lit: set[int] | None, *spots: tuple[float, float, float]):
    px = np.array([s[:2] for s in spots], dtype=float).reshape(-1, 2)
    inten = np.array([s[2] for s in spots], dtype=float)
    return ident.observe(t_ms * MS, None if lit is None else frozenset(lit), px, inten)


def test_single_lit_spot_is_that_landmark_and_the_stray_is_ignored() -> None:
    ident = _ident()
    _obs(ident, 0, set(), (*STRAY, 900.0))
    new = _obs(ident, 33, {2}, (*STRAY, 900.0), (300.0, 200.0, 500.0))
    assert [(s.landmark_id, s.pixel) for s in new] == [(2, (300.0, 200.0))]
    assert not ident.done


def test_landmark_out_of_view_is_not_fooled_by_an_always_on_stray() -> None:
    ident = _ident()
    _obs(ident, 0, set(), (*STRAY, 900.0))
    assert _obs(ident, 33, {1}, (*STRAY, 900.0)) == []
    assert _obs(ident, 66, {2}, (101.0, 100.5, 900.0)) == []
    assert ident.sightings == {}


def test_brightest_new_spot_wins_over_a_reflection() -> None:
    ident = _ident()
    _obs(ident, 0, set())
    new = _obs(ident, 33, {3}, (50.0, 60.0, 120.0), (400.0, 300.0, 800.0))
    assert new[0].pixel == (400.0, 300.0)


def test_without_a_reference_before_the_next_dark_frame_decides() -> None:
    ident = _ident()
    assert _obs(ident, 0, {1}, (200.0, 200.0, 500.0), (*STRAY, 900.0)) == []
    new = _obs(ident, 33, {2}, (*STRAY, 900.0), (250.0, 250.0, 500.0))
    # Frame 33 verifies landmark 1 (its spot is gone) and, with frame 0 as its own
    # reference, identifies landmark 2.
    assert {s.landmark_id: s.pixel for s in new} == {1: (200.0, 200.0), 2: (250.0, 250.0)}


def test_blinking_stray_that_lit_with_the_led_is_revoked() -> None:
    ident = _ident()
    _obs(ident, 0, set())
    _obs(ident, 33, {1}, (220.0, 180.0, 300.0))  # L1 out of view; a blinker turned on
    assert 1 in ident.sightings
    _obs(ident, 66, {2}, (220.0, 180.0, 300.0), (400.0, 100.0, 600.0))
    assert 1 not in ident.sightings
    assert ident.sightings[2].pixel == (400.0, 100.0)


def test_match_radius_grows_with_image_motion() -> None:
    ident = Identifier(
        IdentificationConfig(), [1, 2], motion_px=lambda a, b: 300.0 * abs(b - a) * 1e-9
    )
    _obs(ident, 0, set(), (*STRAY, 900.0))
    # The stray moved 8 px in 33 ms (the robot turns): still recognised as the stray.
    assert _obs(ident, 33, {1}, (108.0, 100.0, 900.0)) == []


def test_sweep_requests_dark_then_one_at_a_time_then_all() -> None:
    ident = _ident()
    assert ident.next_request(0) == LedRequest(lit=frozenset())
    assert ident.next_request(1 * MS) is None  # no frame in the dark yet
    ident.led_confirmed(2 * MS, frozenset())
    _obs(ident, 10, set(), (*STRAY, 900.0))
    assert ident.next_request(11 * MS) == LedRequest(lit=frozenset({1}))
    ident.led_confirmed(20 * MS, frozenset({1}))
    _obs(ident, 43, {1}, (*STRAY, 900.0), (10.0, 20.0, 400.0))
    assert ident.next_request(44 * MS) == LedRequest(lit=frozenset({2}))
    ident.led_confirmed(50 * MS, frozenset({2}))
    _obs(ident, 76, {2}, (*STRAY, 900.0), (30.0, 20.0, 400.0))
    assert ident.done
    assert ident.next_request(77 * MS) == LedRequest(all_lit=True)
    assert ident.next_request(78 * MS) is None


def test_dead_landmark_times_out_and_is_skipped() -> None:
    ident = _ident(led_timeout_s=0.2)
    ident.next_request(0)
    ident.led_confirmed(1 * MS, frozenset())
    _obs(ident, 5, set())
    assert ident.next_request(6 * MS) == LedRequest(lit=frozenset({1}))
    # No confirmation ever comes (dead radio): still waiting before the timeout ...
    assert ident.next_request(150 * MS) is None
    # ... and moves on after it.
    assert ident.next_request(220 * MS) == LedRequest(lit=frozenset({2}))


def test_landmark_without_a_spot_is_skipped_after_its_frames() -> None:
    ident = _ident(frames_per_led=2)
    ident.next_request(0)
    ident.led_confirmed(1 * MS, frozenset())
    _obs(ident, 5, set())
    ident.next_request(6 * MS)
    ident.led_confirmed(7 * MS, frozenset({1}))
    _obs(ident, 38, {1})
    assert ident.next_request(39 * MS) is None
    _obs(ident, 71, {1})
    assert ident.next_request(72 * MS) == LedRequest(lit=frozenset({2}))


def test_candidate_order_and_restart_after_all_tried() -> None:
    ident = _ident(frames_per_led=1)
    ident.restart([3, 1, 2])
    ident.next_request(0)
    ident.led_confirmed(1 * MS, frozenset())
    _obs(ident, 2, set())
    seen = []
    t = 3
    for _ in range(3):
        req = ident.next_request(t * MS)
        assert req is not None
        seen.append(next(iter(req.lit)))
        ident.led_confirmed((t + 1) * MS, req.lit)
        _obs(ident, t + 2, set(req.lit))
        t += 3
    assert seen == [3, 1, 2]
    # Nothing found: start over with a fresh dark frame.
    assert ident.next_request(t * MS) == LedRequest(lit=frozenset())


def test_config_validation() -> None:
    with pytest.raises(ValueError):
        IdentificationConfig(landmarks_needed=1)
    with pytest.raises(ValueError, match="probe"):
        IdentificationConfig(probe="all_at_once")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="dark"):
        LedRequest(lit=frozenset({1}), dark=frozenset({2}))


# -- darkening one landmark of a lit ceiling --------------------------------------------------
ALL = {1, 2, 3}
A, B, C = (200.0, 150.0, 500.0), (320.0, 260.0, 480.0), (420.0, 330.0, 510.0)


def _dark_ident(**kw: object) -> Identifier:
    return Identifier(
        IdentificationConfig(probe="darken_one", **kw),  # type: ignore[arg-type]
        [1, 2, 3],
        positions=np.array([[0.0, 0.0, 2.5], [5.0, 0.0, 2.5], [0.6, 0.0, 2.5]]),
        image_size=(640, 480),
        motion_px=lambda a, b: 0.0,
    )


def test_darkened_landmark_is_identified_when_it_vanishes_and_comes_back() -> None:
    ident = _dark_ident()
    _obs(ident, 0, ALL, A, B, C, (*STRAY, 900.0))
    # 1 darkened: A vanished. Against a lit ceiling one switch is not enough ...
    assert _obs(ident, 33, ALL - {1}, B, C, (*STRAY, 900.0)) == []
    assert [e.appeared for e in ident.evidence[1]] == [False]
    # ... 1 relit and 2 darkened: A came back at the same place, B vanished.
    new = _obs(ident, 66, ALL - {2}, A, C, (*STRAY, 900.0))
    assert {s.landmark_id: s.pixel for s in new} == {1: A[:2]}
    new = _obs(ident, 99, ALL, A, B, C, (*STRAY, 900.0))
    assert {s.landmark_id: s.pixel for s in new} == {2: B[:2]}
    assert ident.done


def test_a_spot_that_vanished_elsewhere_is_not_confirmed() -> None:
    ident = _dark_ident()
    _obs(ident, 0, ALL, A, B)
    _obs(ident, 33, ALL - {1}, B)  # A vanished (say, a person stepped under it)
    _obs(ident, 66, ALL - {2}, (500.0, 100.0, 500.0))  # relit 1 shows up somewhere else
    assert 1 not in ident.sightings


def test_spots_at_the_border_or_ambiguous_changes_give_no_evidence() -> None:
    ident = _dark_ident()
    edge = (2.0, 240.0, 700.0)
    _obs(ident, 0, ALL, A, B, edge)
    _obs(ident, 33, ALL - {1}, A, B)  # only the spot at the border went: leaving the view
    assert ident.evidence == {}
    ident = _dark_ident()
    _obs(ident, 0, ALL, A, B, C)
    _obs(ident, 33, ALL - {2}, A)  # B and C (about as bright) both vanished: ambiguous
    assert ident.evidence == {}


def test_frames_with_a_switch_in_flight_are_not_used() -> None:
    ident = _dark_ident()
    _obs(ident, 0, ALL, A, B)
    _obs(ident, 33, None, B)  # unknown state: A may or may not be switched yet
    assert ident.evidence == {}


def test_darken_requests_try_the_found_landmarks_neighbours_first() -> None:
    ident = _dark_ident(frames_per_led=1)
    _obs(ident, 0, ALL, A, C)
    req = ident.next_request(1 * MS)
    assert req == LedRequest(all_lit=True, dark=frozenset({1}))
    ident.led_confirmed(2 * MS, frozenset(ALL - {1}))
    _obs(ident, 33, ALL - {1}, C)  # landmark 1 shows itself
    # Landmark 3 is 0.6 m from landmark 1, landmark 2 is 5 m away: 3 goes first.
    assert ident.next_request(34 * MS) == LedRequest(all_lit=True, dark=frozenset({3}))
    ident.led_confirmed(40 * MS, frozenset(ALL - {3}))
    _obs(ident, 66, ALL - {3}, A)
    assert set(ident.sightings) == {1}
    assert ident.next_request(67 * MS) == LedRequest(all_lit=True, dark=frozenset({2}))
    ident.led_confirmed(70 * MS, frozenset(ALL - {2}))
    _obs(ident, 99, ALL - {2}, A, C)
    assert set(ident.sightings) == {1, 3} and ident.done
    assert ident.next_request(100 * MS) == LedRequest(all_lit=True)
