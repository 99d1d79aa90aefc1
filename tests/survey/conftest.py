from __future__ import annotations

import math

import numpy as np
import pytest

from sim.survey_floor import SpotDrive, simulate_survey_spots, survey_floor_scenario
from survey.blinks import BlinkConfig, blink_schedule

NS = 1_000_000_000
DRIVE_S = 40.0


@pytest.fixture(scope="package")
def spot_drive() -> SpotDrive:
    """A 40 s survey drive over 12 landmarks (spot level: no rendering), calibration error on."""
    scenario = survey_floor_scenario(
        seed=3, n_landmarks=12, size_m=(4.0, 3.0), lane_spacing_m=1.5, speed_mps=0.4
    )
    ids = sorted(lm.id for lm in scenario.landmarks)
    return simulate_survey_spots(
        scenario, DRIVE_S, lambda t: blink_schedule(ids, t, round(DRIVE_S * NS), BlinkConfig()),
        seed=3,
    )  # fmt: skip


def rough_records(drive: SpotDrive, anchors: list[int], seed: int = 1) -> dict[str, object]:
    """map.json with the anchors as surveyed and every other landmark off by up to 30 cm."""
    rng = np.random.default_rng(seed)
    out = []
    for rec in drive.map_records:
        rec = dict(rec)
        if rec["id"] not in anchors:
            a, r = rng.uniform(0, math.tau), 0.3 * math.sqrt(rng.uniform())
            rec["x"] = float(rec["x"]) + r * math.cos(a)  # type: ignore[arg-type]
            rec["y"] = float(rec["y"]) + r * math.sin(a)  # type: ignore[arg-type]
            rec["z"] = float(rec["z"]) + rng.uniform(-0.1, 0.1)  # type: ignore[arg-type]
        out.append(rec)
    return {"landmarks": out}


def corner_anchors(drive: SpotDrive) -> list[int]:
    """The two landmarks farthest apart."""
    ids = sorted(drive.landmarks_true)
    p = np.array([drive.landmarks_true[i][:2] for i in ids])
    d = np.linalg.norm(p[:, None] - p[None], axis=2)
    i, j = np.unravel_index(int(np.argmax(d)), d.shape)
    return [ids[int(i)], ids[int(j)]]
