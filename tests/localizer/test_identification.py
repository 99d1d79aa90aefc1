"""One-at-a-time identification (Sec. III-A) from LED states and spots."""

from __future__ import annotations

import numpy as np
import pytest

from localizer.events import LedRequest
from localizer.identification import IdentificationConfig, Identifier

MS = 1_000_000
STRAY = (100.0, 100.0)


def _ident(**kw: object) -> Identifier:
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
