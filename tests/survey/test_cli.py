from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from irloc.simulated_recording import simulate_recording
from sim.survey_floor import survey_floor_scenario
from survey.blinks import BlinkConfig, blink_schedule
from survey.cli import main

NS = 1_000_000_000
DRIVE_S = 16.0


def _recording(
    tmp_path_factory: pytest.TempPathFactory, drive_s: float
) -> tuple[Path, dict[int, np.ndarray]]:
    """A rendered survey drive of `drive_s` over 9 landmarks; map.json: the corners surveyed,
    the rest off by up to 30 cm, two with no position."""
    scenario = survey_floor_scenario(
        seed=5, n_landmarks=9, size_m=(3.0, 3.0), lane_spacing_m=1.2, speed_mps=0.4
    )
    ids = sorted(lm.id for lm in scenario.landmarks)
    root = tmp_path_factory.mktemp("survey") / "rec"
    simulate_recording(
        scenario, root, duration_s=drive_s,
        led_program=lambda t: blink_schedule(ids, t, round(drive_s * NS), BlinkConfig()),
    )  # fmt: skip
    truth = {lm.id: np.array([lm.x, lm.y, lm.z]) for lm in scenario.landmarks}
    doc = json.loads((root / "map.json").read_text())
    rng = np.random.default_rng(2)
    for rec in doc["landmarks"]:
        if rec["id"] in (ids[0], ids[-1]):
            continue
        if rec["id"] in (ids[3], ids[5]):
            del rec["x"], rec["y"], rec["z"]
            continue
        a, r = rng.uniform(0, math.tau), 0.3 * math.sqrt(rng.uniform())
        rec["x"] += r * math.cos(a)
        rec["y"] += r * math.sin(a)
    (root / "map.json").write_text(json.dumps(doc))
    return root, truth


@pytest.fixture(scope="module")
def recording(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[int, np.ndarray]]:
    """The 16 s drive the survey places every landmark from."""
    return _recording(tmp_path_factory, DRIVE_S)


@pytest.fixture(scope="module")
def short_recording(
    tmp_path_factory: pytest.TempPathFactory,
) -> tuple[Path, dict[int, np.ndarray]]:
    """A 1 s drive with the same map.json: for the input errors, found before any solve (each
    read of the 16 s drive's frames takes seconds)."""
    return _recording(tmp_path_factory, 1.0)


def test_survey_writes_every_landmark_within_a_centimetre(recording, tmp_path, capsys) -> None:  # type: ignore[no-untyped-def]
    root, truth = recording
    ids = sorted(truth)
    out = tmp_path / "surveyed.json"
    assert (
        main([str(root), "--anchor", str(ids[0]), "--anchor", str(ids[-1]), "--out", str(out)]) == 0
    )
    table = capsys.readouterr().out
    assert "anchor" in table and "wrote" in table
    doc = json.loads(out.read_text())
    assert [r["id"] for r in doc["landmarks"]] == ids
    for rec in doc["landmarks"]:
        p = np.array([rec["x"], rec["y"], rec["z"]])
        assert np.hypot(*(p - truth[rec["id"]])[:2]) < 0.01, rec
        assert abs(p[2] - truth[rec["id"]][2]) < 0.02, rec
        assert "radio" in rec  # other keys kept
        if rec["id"] not in (ids[0], ids[-1]):
            assert 0 < rec["sigma_m"] < 0.05


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--anchor", "100"], "needs two or more anchors"),
        (["--anchor", "100", "--anchor", "7777"], "anchor 7777 is not in map.json"),
    ],
)
def test_bad_input_is_one_line_and_writes_nothing(
    short_recording, tmp_path, capsys, args, message
) -> None:  # type: ignore[no-untyped-def]
    root, _ = short_recording
    out = tmp_path / "out.json"
    assert main([str(root), *args, "--out", str(out), "--quiet"]) == 1
    err = capsys.readouterr().err.strip()
    assert err.startswith("irloc survey: ") and message in err and "\n" not in err
    assert not out.exists()


def test_no_odometry_and_not_a_recording(short_recording, tmp_path, capsys) -> None:  # type: ignore[no-untyped-def]
    root, truth = short_recording
    ids = sorted(truth)
    copy = tmp_path / "rec"
    import shutil

    shutil.copytree(root, copy)
    (copy / "odom0" / "data.csv").unlink()
    out = tmp_path / "out.json"
    anchors = ["--anchor", str(ids[0]), "--anchor", str(ids[-1])]
    assert main([str(copy), *anchors, "--out", str(out)]) == 1
    assert "no odometry" in capsys.readouterr().err
    assert main([str(tmp_path / "nope"), *anchors, "--out", str(out)]) == 1
    assert "not a recording folder" in capsys.readouterr().err
    assert not out.exists()
