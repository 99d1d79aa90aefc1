"""The frame's timing (`frame_report.FrameTiming`)."""

from __future__ import annotations

import pytest

from localizer.frame_report import FrameTiming

MS = 1_000_000


def test_the_usual_frame_interval_follows_the_frames_and_ignores_a_long_pause() -> None:
    timing = FrameTiming()
    assert timing.frame(0) == (0.0, {"gap_s": 0.0, "typical_gap_s": 0.0})  # the first
    dt, notes = timing.frame(50 * MS)
    assert dt == pytest.approx(0.05) and notes["typical_gap_s"] == 0.0  # the usual one before
    assert timing.typical_gap_s == pytest.approx(0.05) and timing.interval_s == dt
    timing.frame(150 * MS)  # one frame late: the usual interval moves a tenth of the way
    assert timing.typical_gap_s == pytest.approx(0.055)
    dt, notes = timing.frame(5_150 * MS)  # a 5 s pause: capped at 1 s, not learnt
    assert dt == 1.0 and notes["gap_s"] == 1.0 and timing.typical_gap_s == pytest.approx(0.055)
