"""Naming spots without blinks (`survey.association`): the joint assignment and its margin,
the clustering of tracks, and whole drives with every LED lit after a two-anchor start."""

from __future__ import annotations

import math

import numpy as np
import pytest

from localizer.robot import RobotGeometry
from sim.lit_site import anchor_pair, anchor_sweep_then_lit, lit_site_scenario, taped_map
from sim.survey_floor import SpotDrive, simulate_survey_spots
from survey.association import TrackPoint, assign, cluster_tracks
from survey.bundle import BundleConfig, solve_survey
from survey.drive import SurveyDrive, survey_problem
from survey.survey_map import parse_survey_map

SIG = 0.15  # the rough positions' sigma, metres
GATE, MARGIN = 18.42, 13.8


def _assign(
    points: list[tuple[float, float]], rough: list[tuple[float, float]], cov_m: float = 0.01
) -> tuple[dict[int, int], dict[int, set[int]]]:
    pc = np.array([cov_m**2 * np.eye(2)] * len(points))
    ec = np.array([SIG**2 * np.eye(2)] * len(rough))
    return assign(
        np.array(points, dtype=float), pc, list(range(len(rough))), np.array(rough, dtype=float),
        ec, GATE, MARGIN,
    )  # fmt: skip


def test_neighbours_are_named_jointly_where_the_nearest_rough_position_is_wrong() -> None:
    # the second landmark's nearest rough position is the first's (50 cm against 52 cm):
    # taken together, the first is surely that one, and the second its own
    named, doubt = _assign([(0.0, 0.0), (0.7, 0.0)], [(0.2, 0.0), (0.7, 0.52)])
    assert named == {0: 0, 1: 1}
    assert doubt == {}


def test_landmarks_closer_than_their_rough_positions_tell_apart_stay_unnamed() -> None:
    # 30 cm apart, each taped 25 cm toward the other: the best assignment is the swap, by a
    # margin far under the odds asked: neither is named (never the wrong one), each names
    # the other as the neighbour it could be
    named, doubt = _assign([(0.0, 0.0), (0.3, 0.0)], [(0.25, 0.0), (0.05, 0.0)])
    assert named == {}
    assert doubt == {0: {1}, 1: {0}}


def test_a_spot_far_from_every_landmark_names_nothing_and_a_lone_landmark_is_named() -> None:
    named, doubt = _assign([(0.1, -0.1), (3.0, 3.0)], [(0.0, 0.0), (1.5, 0.0)])
    assert named == {0: 0}
    assert doubt == {}


def test_a_placed_landmark_takes_every_cluster_of_it() -> None:
    # two clusters of one placed landmark (their drives' poses disagree by 4 cm): one entry
    # per cluster that may be it, and a taped neighbour 70 cm away is not confused with it
    pts = np.array([[0.0, 0.0], [0.04, 0.0], [0.72, 0.05]])
    pc = np.array([0.02**2 * np.eye(2)] * 3)
    entry_of = [7, 7, 8]
    exy = np.array([[0.02, 0.0], [0.02, 0.0], [0.8, 0.1]])
    ec = np.array([1e-6 * np.eye(2), 1e-6 * np.eye(2), SIG**2 * np.eye(2)])
    named, doubt = assign(pts, pc, entry_of, exy, ec, GATE, MARGIN)
    assert named == {0: 7, 1: 7, 2: 8}
    assert doubt == {}


def _tp(x: float, y: float, frames: range, s: float = 0.01) -> TrackPoint:
    return TrackPoint(np.array([x, y]), s**2 * np.eye(2), np.array([0]), frozenset(frames))


def test_tracks_of_one_landmark_merge_and_tracks_seen_together_never_do() -> None:
    poses = np.zeros((1, 3))
    points = {
        0: _tp(0.0, 0.0, range(0, 10)),
        1: _tp(0.01, 0.0, range(20, 30)),  # the same landmark later
        2: _tp(0.02, 0.0, range(5, 15)),  # as close, but seen with track 0: another spot
        3: _tp(1.0, 0.0, range(0, 10)),
    }
    clusters = cluster_tracks(points, poses, GATE)
    groups = sorted(sorted(c.tracks) for c in clusters)
    assert [0, 1] in groups
    assert [3] in groups
    assert all(not ({0, 2} <= set(g)) for g in groups)


def _drive(seed: int, close_pairs: int, seconds: float) -> tuple[SpotDrive, list[int], SurveyDrive]:
    scenario = lit_site_scenario(seed=seed, close_pairs=close_pairs)
    anchors = anchor_pair(scenario)
    drive = simulate_survey_spots(
        scenario, seconds, lambda t: anchor_sweep_then_lit(anchors), seed=seed
    )
    doc = taped_map(drive.map_records, anchors, np.random.default_rng(seed))
    sd = SurveyDrive(
        parse_survey_map(doc, source="test map"), drive.camera, RobotGeometry(drive.wheel_base_m),
        drive.frame_t_ns, drive.frame_spots, drive.odom_t_ns, drive.odom_v, drive.leds, 0,
    )  # fmt: skip
    return drive, anchors, sd


@pytest.mark.parametrize("seed", [3])
def test_a_drive_with_every_led_lit_places_every_landmark_from_two_anchors(seed: int) -> None:
    """The everyday drive: two anchors lit one at a time, then everything lit; every other
    landmark taped (sigma 12 cm, up to 30 cm off, neighbours down to 70 cm)."""
    drive, anchors, sd = _drive(seed, 0, 75.0)
    problem = survey_problem(sd, anchors)
    assert problem.observations.seen_ids() == set(anchors)  # only the anchors were blinked
    result = solve_survey(problem, BundleConfig())
    assert result.unseen == ()
    for lid, e in result.landmarks.items():
        d = e.position - drive.landmarks_true[lid]
        assert math.hypot(d[0], d[1]) < 0.02, (lid, d)  # 75 s: one pass (the bench: 3 min)
        assert abs(d[2]) < 0.02, (lid, d)
        if not e.anchor:  # within 3 sigma (x-y Mahalanobis^2 <= 11.8)
            assert float(d[:2] @ np.linalg.solve(e.covariance[:2, :2], d[:2])) < 11.8, lid


def test_landmarks_too_close_for_the_tape_are_reported_and_none_is_named_wrongly() -> None:
    """Three extra landmarks 30 cm from a neighbour: the survey names what it can, each
    landmark it places is right, and each it cannot is reported with the reason."""
    drive, anchors, sd = _drive(31, 3, 75.0)
    result = solve_survey(survey_problem(sd, anchors), BundleConfig())
    for lid, e in result.landmarks.items():
        d = e.position - drive.landmarks_true[lid]
        assert math.hypot(d[0], d[1]) < 0.02, (lid, d)  # a wrong name would be >= 30 cm off
    assert result.unseen
    assert set(result.unnamed) == set(result.unseen)
    close = [lid for lid, why in result.unnamed.items() if why.startswith("too close")]
    assert close, result.unnamed
    ids = sorted(drive.landmarks_true)
    p = np.array([drive.landmarks_true[i][:2] for i in ids])
    for lid in close:  # each has a true neighbour within 40 cm
        d = np.hypot(*(p - drive.landmarks_true[lid][:2]).T)
        assert np.sort(d)[1] < 0.4, lid
