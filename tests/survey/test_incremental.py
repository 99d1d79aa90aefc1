"""The incremental survey (a fixed-lag smoother over the bundle adjustment): bounded
windows, the same answer as the whole-drive solve within its uncertainty, honest
covariances, the marginal prior's algebra, and its state file."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp

from bench.bench_survey import truncated
from sim.survey_floor import SpotDrive
from survey.bundle import BundleConfig, solve_survey
from survey.drive import SurveyDrive, survey_problem
from survey.incremental import IncrementalConfig, IncrementalSurvey, update, window_of
from survey.incremental_file import load, save
from survey.result import SurveyResult
from survey.sparse_lm import GaussianPrior, levenberg_marquardt
from tests.survey.conftest import NS, corner_anchors, rough_records

CFG = BundleConfig(max_iterations=12, window_iterations=4)
Driven = tuple[IncrementalSurvey, list[int], SurveyResult, list[int]]


def upto(drive: SpotDrive, seconds: float, records: dict[str, object]) -> SurveyDrive:
    return truncated(drive, seconds, records)


@pytest.fixture(scope="module")
def driven(spot_drive: SpotDrive) -> Driven:
    """The 40 s drive surveyed incrementally (an update every 4 s, lag 6 s), the window
    sizes, and the whole-drive solve."""
    anchors = corner_anchors(spot_drive)
    records = rough_records(spot_drive, anchors)
    inc = IncrementalConfig(lag_s=6.0)
    state, windows = IncrementalSurvey(), []
    for t in range(4, 41, 4):
        window = window_of(upto(spot_drive, t, records), state.window_start_ns)
        windows.append(len(window.frame_t_ns))
        try:
            state = update(state, window, anchors, CFG, inc)
        except ValueError as exc:  # an anchor not identified yet
            assert "never identified" in str(exc)
    whole = solve_survey(survey_problem(upto(spot_drive, 40, records), anchors), CFG)
    return state, windows, whole, anchors


def test_each_update_solves_a_bounded_window_and_places_what_the_whole_drive_does(
    driven: Driven, spot_drive: SpotDrive
) -> None:
    state, windows, whole, _ = driven
    assert state.prior is not None and state.updates >= 6
    # the window stops growing once keyframes are marginalised: lag + update + slack
    assert max(windows[-4:]) < 12 * 30, windows
    r = state.result
    assert r is not None
    truth = spot_drive.landmarks_true
    free = [e for e in r.landmarks.values() if not e.anchor]
    assert len(free) >= len([e for e in whole.landmarks.values() if not e.anchor]) - 1
    inside = 0
    for e in free:
        d = e.position - truth[e.id]
        assert math.hypot(d[0], d[1]) < 0.01, (e.id, d)
        inside += float(d[:2] @ np.linalg.solve(e.covariance[:2, :2], d[:2])) <= 6.18
        w = whole.landmarks.get(e.id)
        if w is not None:  # the two estimates' sigmas agree to within a factor of two
            assert 0.5 < e.sigma_m / w.sigma_m < 2.0, (e.id, e.sigma_m, w.sigma_m)
    assert inside >= len(free) - 2, (inside, len(free))
    # evidence carried across windows: views add up
    assert all(e.views >= 3 for e in free)
    assert len(r.trajectory_t_ns) == len(r.trajectory) and np.all(np.diff(r.trajectory_t_ns) > 0)


def test_the_state_file_keeps_the_estimate_and_a_restart_drops_the_pose(
    driven: Driven, tmp_path: Path
) -> None:
    state, _, _, anchors = driven
    path = tmp_path / "survey-estimate.npz"
    save(state, path, {"robot": "r1", "anchors": anchors})
    back, extra = load(path)
    assert extra == {"robot": "r1", "anchors": anchors}
    assert back.prior is not None and state.prior is not None
    np.testing.assert_array_equal(back.prior.information, state.prior.information)
    assert back.carried == state.carried and back.updates == state.updates
    assert state.result is not None and back.result is not None
    for lid, e in state.result.landmarks.items():
        np.testing.assert_array_equal(back.result.landmarks[lid].covariance, e.covariance)
        assert back.result.landmarks[lid].flags == e.flags
    again = back.restarted()
    assert again.prior is not None and not again.prior.has_pose
    assert len(again.prior.mean) == len(state.prior.mean) - 3
    # the landmarks' information without the pose is the Schur complement: never more
    full = np.linalg.inv(state.prior.information)[3:, 3:]
    np.testing.assert_allclose(np.linalg.inv(again.prior.information), full, rtol=1e-6)
    path.write_bytes(b"not a state")
    with pytest.raises(ValueError, match="not a survey state"):
        load(path)


def test_a_gaussian_prior_in_the_solver_is_the_data_it_stands_for() -> None:
    """Solving y = A x in two halves, the first marginalised into a prior on the shared
    unknowns, gives the whole problem's answer (linear: exact)."""
    rng = np.random.default_rng(4)
    A = rng.normal(size=(40, 3))
    y = A @ np.array([1.0, -2.0, 0.5]) + rng.normal(0, 0.1, 40)
    whole = np.linalg.lstsq(A, y, rcond=None)[0]
    A1, y1, A2, y2 = A[:20], y[:20], A[20:], y[20:]
    info = A1.T @ A1
    mean = np.linalg.solve(info, A1.T @ y1)
    res = levenberg_marquardt(
        lambda x: A2 @ x - y2, np.zeros(3), sp.csr_matrix(np.ones((20, 3))),
        np.arange(3), np.full(3, 1e-6), huber_k=1e9, max_iterations=20,
        prior=GaussianPrior(np.arange(3), mean, info),
    )  # fmt: skip
    np.testing.assert_allclose(res.x, whole, atol=1e-5)


def test_a_window_must_begin_at_its_kept_keyframe(driven: Driven, spot_drive: SpotDrive) -> None:
    state, _, _, anchors = driven
    records = rough_records(spot_drive, anchors)
    wrong = window_of(upto(spot_drive, 40, records), None)
    wrong = dataclasses.replace(wrong, frame_t_ns=wrong.frame_t_ns + 1)
    with pytest.raises(ValueError, match="kept keyframe"):
        update(state, wrong, anchors, CFG, IncrementalConfig(lag_s=6.0))


def test_after_a_restart_the_drive_goes_on_from_the_landmarks_alone(
    driven: Driven, spot_drive: SpotDrive
) -> None:
    """A drive resumed after a gap in the wheels' record starts its window where it is: its
    first pose is free (found from the landmarks the prior holds), the landmarks keep what
    the drive before the gap said of them."""
    state, _, _, anchors = driven
    records = rough_records(spot_drive, anchors)
    again = state.restarted()
    later = window_of(upto(spot_drive, 40, records), 28 * NS)  # the robot seen again at 28 s
    after = update(again, later, anchors, CFG, IncrementalConfig(lag_s=6.0))
    assert after.prior is not None and after.prior.has_pose and after.result is not None
    assert state.result is not None
    truth = spot_drive.landmarks_true
    for lid, e in after.result.landmarks.items():
        if not e.anchor:
            d = e.position - truth[lid]
            assert math.hypot(d[0], d[1]) < 0.01, (lid, d)
    assert set(after.result.landmarks) >= set(state.result.landmarks) - set(anchors)
