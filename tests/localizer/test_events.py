from __future__ import annotations

from localizer.events import LedsChanged


def test_lit_among_expands_all_lit_to_the_landmarks_given() -> None:
    assert LedsChanged(0, all_lit=True).lit_among({3: "a", 1: "b"}) == frozenset({1, 3})
    assert LedsChanged(0, frozenset({2})).lit_among([1, 2, 3]) == frozenset({2})
    assert LedsChanged(0).lit_among([1, 2]) == frozenset()
