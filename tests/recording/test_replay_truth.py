"""`irloc replay --truth`: the Sec. V table in the terminal, the same figures as scoring the
poses.csv it wrote."""

from __future__ import annotations

from pathlib import Path

import pytest

from recording.reader import read_groundtruth, read_recording
from recording.replay_cli import main
from recording.scoring import read_poses, sec_v


def test_prints_the_sec_v_table_against_groundtruth_beside_the_recording(
    testbed_recording: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "poses.csv"
    assert main([str(testbed_recording), "--out", str(out)]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0] == f"against {testbed_recording / 'groundtruth.csv'}"
    t_gt, gt = read_groundtruth(testbed_recording)
    sweep_end = next(e.t_ns for e in read_recording(testbed_recording).leds if e.all_lit)
    expected = sec_v(read_poses(out), t_gt, gt, sweep_end_ns=sweep_end).figures
    assert expected["stops"] >= 1
    assert lines[1] == f"Sec. V figures over {int(expected['stops'])} parked stops"
    table = {line[:28].strip(): line[28:].split() for line in lines[3:9]}
    assert table["mean position error, cm"] == [f"{expected['mean_cm']:.3f}", "4.10"]
    assert table["jitter, deg"] == [f"{expected['jitter_deg']:.3f}", "0.30"]
    assert expected["mean_cm"] < 2.0 and expected["jitter_cm"] < 0.5
    assert lines[9].startswith("every frame with a pose")
    assert lines[10].startswith("modes: landmark")


def test_truth_from_another_file_and_none(
    testbed_recording: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    truth = tmp_path / "elsewhere.csv"
    truth.write_text((testbed_recording / "groundtruth.csv").read_text())
    out = tmp_path / "poses.csv"
    assert main([str(testbed_recording), "--out", str(out), "--truth", str(truth)]) == 0
    assert capsys.readouterr().out.startswith(f"against {truth}\n")
    assert main([str(testbed_recording), "--out", str(out), "--no-truth"]) == 0
    assert capsys.readouterr().out == ""
    truth.write_text("timestamp_ns,x,y,theta\n0,1,2,fast\n")
    assert main([str(testbed_recording), "--out", str(out), "--truth", str(truth)]) == 1
    assert "elsewhere.csv:2: theta must be a number" in capsys.readouterr().err
