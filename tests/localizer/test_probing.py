"""The probe plan (localizer/probing.py) with the identifier: one-sided landmarks are probed
again at once, stale evidence neither pairs nor ends a probe, the command latency is
measured."""

from __future__ import annotations

import numpy as np
import pytest

from localizer.events import LedRequest
from localizer.identification import IdentificationConfig, Identifier

MS = 1_000_000
ALL = frozenset({1, 2, 3, 4, 5})
A = (100.0, 100.0, 500.0)  # landmark 1's spot, always lit here
P3 = (300.0, 200.0, 600.0)  # landmark 3's spot


def _ident(**kw: object) -> Identifier:
    cfg = IdentificationConfig(probe="darken_one", frames_per_led=2, **kw)  # type: ignore[arg-type]
    return Identifier(cfg, sorted(ALL), motion_px=lambda a, b: 0.0)


def _obs(ident: Identifier, t_ms: int, lit: frozenset[int], *spots: tuple[float, float, float]):
    px = np.array([s[:2] for s in spots], dtype=float).reshape(-1, 2)
    inten = np.array([s[2] for s in spots], dtype=float)
    ident.led_confirmed(t_ms * MS, lit)
    return ident.observe(t_ms * MS, lit, px, inten)


def test_a_landmark_seen_on_one_side_only_is_darkened_again_at_once() -> None:
    ident = _ident()
    assert ident.next_request(0) == LedRequest(all_lit=True, dark=frozenset({1}))
    # Another robot's probe of 3 ends: 3 came back (its darkening was not seen here).
    _obs(ident, 10, ALL - {1, 3}, A)
    _obs(ident, 43, ALL - {1}, P3)
    _obs(ident, 76, ALL - {1}, P3)
    assert ident.evidence.keys() == {3} and 3 not in ident.sightings
    # 1 finished its frames: 3, in view now, is darkened again before 2.
    assert ident.next_request(80 * MS) == LedRequest(all_lit=True, dark=frozenset({3}))
    new = _obs(ident, 110, ALL - {3}, A)
    assert [s.landmark_id for s in new] == [3] and new[0].pixel == P3[:2]


def test_stale_evidence_expires_and_does_not_end_a_new_probe_of_it() -> None:
    ident = _ident()
    ident.next_request(0)
    _obs(ident, 10, ALL, A, P3)
    _obs(ident, 43, ALL - {3}, A)  # 3 vanished under someone's probe; its return unseen
    assert 3 in ident.evidence
    _obs(ident, 2000, ALL, A)  # 2 s later: it can no longer pair
    assert 3 not in ident.evidence
    assert ident.anchor is not None and ident.anchor.landmark_id == 3  # still orders
    ident.prefer([3])
    assert ident.next_request(2010 * MS) == LedRequest(all_lit=True, dark=frozenset({3}))
    _obs(ident, 2043, ALL - {3}, A)
    assert ident.next_request(2050 * MS) is None  # one frame in force, no new evidence


@pytest.mark.parametrize(("flight", "expected"), [(True, 0.7 * 0.3 + 0.3 * 0.45), (False, 0.3)])
def test_the_command_latency_is_measured_from_request_to_confirmed_switch(
    flight: bool, expected: float
) -> None:
    ident = _ident()
    assert ident.next_request(0) == LedRequest(all_lit=True, dark=frozenset({1}))
    if flight:
        ident.led_confirmed(50 * MS, None)  # the switch announced, in flight
    ident.led_confirmed(450 * MS, ALL - {1})
    assert ident.probes.latency_s == pytest.approx(expected)
