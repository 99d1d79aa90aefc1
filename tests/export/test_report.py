"""`irloc report`: the self-contained HTML of a simulated test-bed recording, its Sec. V table
(the figures `recording.scoring` computes, beside the paper's) and its figures."""

from __future__ import annotations

import base64
import re
from pathlib import Path

import cv2
import numpy as np
import pytest

from export.report import collect, render_html
from export.report_cli import main
from recording.reader import read_groundtruth


def test_report_of_the_test_bed(
    testbed_recording: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "report.html"
    assert main([str(testbed_recording), "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert printed.splitlines()[0].startswith("Sec. V figures over ")
    assert f"wrote {out}" in printed
    text = out.read_text(encoding="utf-8")
    assert "http://" not in text and "https://" not in text  # self-contained
    images = re.findall(r'<img src="data:image/png;base64,([A-Za-z0-9+/=]+)"', text)
    assert len(images) == 6  # Fig. 9, Fig. 10, error by mode, jitter, landmarks, time
    for data in images:
        png = cv2.imdecode(np.frombuffer(base64.b64decode(data), np.uint8), cv2.IMREAD_COLOR)
        assert png is not None and png.shape[1] > 600 and png.std() > 5  # drawn, not blank
    rows = dict(re.findall(r"<tr><td>([^<]+)</td><td class=n>([^<]+)</td><td class=n>", text))
    assert set(rows) == {
        "mean position error, cm",
        "std, cm",
        "max position error, cm",
        "mean heading error, deg",
        "jitter, cm",
        "jitter, deg",
    }
    assert "<td class=n>4.10</td>" in text and "<td class=n>0.30</td>" in text
    assert float(rows["mean position error, cm"]) < 2.0
    table = {line[:28].strip(): line[28:].split() for line in printed.splitlines()[2:8]}
    assert {k: v[0] for k, v in table.items()} == rows  # the terminal's table is the HTML's
    assert str(testbed_recording / "groundtruth.csv") in text


def test_report_without_truth(testbed_recording: Path) -> None:
    bare = collect(testbed_recording, use_truth=False)
    assert bare.result is None and bare.truth is None
    t_gt, _ = read_groundtruth(testbed_recording)
    assert len(bare.track.t_ns) == len(bare.cpu_s) == len(t_gt)
    assert np.all(bare.cpu_s > 0)
    assert bare.jitters  # parked from the wheels: the start-up stop at least
    assert bare.jitters[0][2] < 0.005
    text = render_html(bare)
    assert "No ground truth" in text
    assert len(re.findall(r"<img ", text)) == 4  # no Fig. 10, no error over time


def test_bad_truth_file_is_one_line(
    testbed_recording: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    truth = tmp_path / "gt.csv"
    truth.write_text("timestamp_ns,x,y,theta\n5,1,2\n")
    out = tmp_path / "r.html"
    assert main([str(testbed_recording), "--out", str(out), "--truth", str(truth)]) == 1
    assert "gt.csv:2: expected 4 fields" in capsys.readouterr().err
    assert not out.exists()
