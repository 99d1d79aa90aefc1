from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from localizer.robot import RobotGeometry
from sim.survey_floor import SpotDrive
from survey.bundle import BundleConfig, solve_survey
from survey.drive import SurveyDrive, survey_problem
from survey.survey_map import parse_survey_map
from tests.survey.conftest import corner_anchors, rough_records


def _drive(d: SpotDrive, records: dict[str, object]) -> SurveyDrive:
    return SurveyDrive(
        parse_survey_map(records, source="test map"), d.camera, RobotGeometry(d.wheel_base_m),
        d.frame_t_ns, d.frame_spots, d.odom_t_ns, d.odom_v, d.leds, 0,
    )  # fmt: skip


@pytest.fixture(scope="module")
def surveyed(spot_drive: SpotDrive):  # type: ignore[no-untyped-def]
    anchors = corner_anchors(spot_drive)
    problem = survey_problem(_drive(spot_drive, rough_records(spot_drive, anchors)), anchors)
    return anchors, solve_survey(problem, BundleConfig())


def test_every_landmark_within_a_centimetre_from_30_cm_rough(surveyed, spot_drive) -> None:  # type: ignore[no-untyped-def]
    _anchors, result = surveyed
    assert set(result.landmarks) == set(spot_drive.landmarks_true)
    errors = [
        e.position - spot_drive.landmarks_true[lid]
        for lid, e in result.landmarks.items()
        if not e.anchor
    ]
    xy = np.hypot(*np.array(errors)[:, :2].T)
    z = np.abs(np.array(errors)[:, 2])
    assert xy.max() < 0.01 and z.max() < 0.02
    # the reported sigmas are honest: errors within 3 sigma of the ellipse
    for lid, e in result.landmarks.items():
        if e.anchor:
            continue
        d = (e.position - spot_drive.landmarks_true[lid])[:2]
        assert float(d @ np.linalg.solve(e.covariance[:2, :2], d)) < 3.0**2 * 2
        assert 0.0005 < e.sigma_m < 0.05


def test_wheels_and_camera_are_estimated(surveyed) -> None:  # type: ignore[no-untyped-def]
    _, result = surveyed
    wl, wr, wb = result.wheel_calibration
    # the simulated robot: radii +0.4 % / -0.3 %, wheel base +1 %
    assert wl == pytest.approx(1.004, abs=0.002)
    assert wr == pytest.approx(0.997, abs=0.002)
    assert wb == pytest.approx(1.01, abs=0.005)
    assert result.rms_px < 0.5
    assert result.converged


def test_a_landmark_moved_in_the_map_is_flagged(spot_drive: SpotDrive) -> None:
    anchors = corner_anchors(spot_drive)
    records = rough_records(spot_drive, anchors)
    victim = next(r for r in records["landmarks"] if r["id"] not in anchors)  # type: ignore[attr-defined]
    victim["x"] = float(victim["x"]) + 1.5
    problem = survey_problem(_drive(spot_drive, records), anchors)
    result = solve_survey(problem, BundleConfig())
    flagged = result.landmarks[int(victim["id"])].flags
    assert any("from its given position" in f for f in flagged)
    # ... and it is still found where it really is
    err = (
        result.landmarks[int(victim["id"])].position - spot_drive.landmarks_true[int(victim["id"])]
    )
    assert math.hypot(err[0], err[1]) < 0.01


def test_bad_input_names_the_problem(spot_drive: SpotDrive) -> None:
    anchors = corner_anchors(spot_drive)
    drive = _drive(spot_drive, rough_records(spot_drive, anchors))
    with pytest.raises(ValueError, match="two or more anchors"):
        survey_problem(drive, anchors[:1])
    with pytest.raises(ValueError, match=r"anchor 999 is not in map\.json"):
        survey_problem(drive, [anchors[0], 999])
    no_odometry = dataclasses.replace(
        drive, odom_t_ns=np.zeros(0, dtype=np.int64), odom_v=np.zeros((0, 2))
    )
    with pytest.raises(ValueError, match="no odometry"):
        survey_problem(no_odometry, anchors)
    problem = survey_problem(drive, anchors)
    unseen = dataclasses.replace(
        problem,
        observations=dataclasses.replace(
            problem.observations,
            landmark_id=np.where(
                problem.observations.landmark_id == anchors[1], -1, problem.observations.landmark_id
            ),
        ),
    )
    with pytest.raises(ValueError, match=f"anchor landmark\\(s\\) {anchors[1]} never identified"):
        solve_survey(unseen)
