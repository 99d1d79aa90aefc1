"""A robot's view against its floor's map: its floor becomes unknown (poses withheld) as soon
as landmarks expected in view go unseen for `unfit_after_s`, and known again when told or
after `own_fix_hold_s` of fixes on its own map."""

from __future__ import annotations

import numpy as np
import pytest

from fleet.floor_fit import FloorFit, FloorFitConfig
from localizer.events import Mode, NoPose, PoseEstimate

MS = 1_000_000


def est(t_ms: int, mode: Mode, expected: tuple[int, ...] = (1, 2)) -> PoseEstimate:
    used = expected if mode == "landmark" else ()
    return PoseEstimate(t_ms * MS, 1.0, 2.0, 0.1, np.eye(3) * 1e-4, mode, used, expected)


def test_landmarks_expected_and_unseen_for_a_second_make_the_floor_unknown() -> None:
    fit = FloorFit(FloorFitConfig(unfit_after_s=1.0, own_fix_hold_s=3.0))
    assert not fit.observe(est(0, "landmark"))
    assert not any(fit.observe(est(t, "dead_reckoning")) for t in range(100, 1100, 100))
    assert fit.observe(est(1100, "dead_reckoning"))  # 1.0 s after the first misfit
    assert fit.unknown and fit.unknown_since_ns == 1100 * MS and fit.withheld == 1
    assert fit.observe(NoPose(1200 * MS, "identifying"))  # no pose: nothing withheld
    assert fit.withheld == 1
    assert fit.last_estimate is not None and fit.last_estimate.t_ns == 1100 * MS


def test_dead_reckoning_with_nothing_expected_in_view_is_no_misfit() -> None:
    """Between sparse landmarks, or in a dark corridor, the robot expects none: it fits."""
    fit = FloorFit()
    fit.observe(est(0, "landmark"))
    assert not any(fit.observe(est(t, "dead_reckoning", ())) for t in range(100, 20_000, 100))


def test_a_fix_breaks_the_misfit_run() -> None:
    fit = FloorFit(FloorFitConfig(unfit_after_s=1.0))
    for t in range(0, 900, 100):
        fit.observe(est(t, "dead_reckoning"))
    fit.observe(est(900, "landmark"))
    assert not any(fit.observe(est(t, "dead_reckoning")) for t in range(1000, 1900, 100))


def test_an_unknown_floor_is_known_again_only_after_fixes_held_without_a_gap() -> None:
    fit = FloorFit(FloorFitConfig(unfit_after_s=0.5, own_fix_hold_s=3.0))
    for t in range(0, 700, 100):
        fit.observe(est(t, "dead_reckoning"))
    assert fit.unknown
    # a moment's fix on a ceiling that only looks like its own: still withheld
    assert all(fit.observe(est(t, "landmark")) for t in range(1000, 2500, 100))
    assert fit.observe(est(2500, "dead_reckoning"))
    assert all(fit.observe(est(t, "landmark")) for t in range(3000, 6000, 100))
    assert not fit.observe(est(6000, "landmark"))  # held 3 s: known, published again
    assert not fit.unknown and fit.unknown_since_ns is None


def test_told_its_floor_the_robot_publishes_at_once() -> None:
    fit = FloorFit(FloorFitConfig(unfit_after_s=0.2))
    for t in range(0, 400, 100):
        fit.observe(est(t, "dead_reckoning"))
    assert fit.unknown
    fit.known()
    assert not fit.observe(est(500, "dead_reckoning"))


@pytest.mark.parametrize("unfit, hold", [(0.0, 1.0), (1.0, -1.0)])
def test_a_bad_configuration_is_refused_naming_it(unfit: float, hold: float) -> None:
    with pytest.raises(ValueError, match="unfit_after_s must be > 0"):
        FloorFitConfig(unfit_after_s=unfit, own_fix_hold_s=hold)
