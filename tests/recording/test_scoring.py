"""Sec. V scoring on tracks with known errors: parked stops, the mean estimate's error, the
heading error and the jitter come out as constructed."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from localizer.events import NoPose, PoseEstimate
from recording.scoring import (
    PAPER,
    PoseTrack,
    error_stats,
    jitter_while_parked,
    odometry_stops,
    parked_stops,
    read_poses,
    sec_v,
    sec_v_table,
    track_from_estimates,
)

NS = 1_000_000_000
DT = NS // 10  # 10 Hz


def _truth() -> tuple[np.ndarray, np.ndarray]:
    """Three 2 s stops at (0, 0, 0), (0.6, 0, 90 deg), (0.6, 0.6, 180 deg), 1 s moves between."""
    stops = [(0.0, 0.0, 0.0), (0.6, 0.0, math.pi / 2), (0.6, 0.6, math.pi)]
    t, poses = [], []
    k = 0
    for i, p in enumerate(stops):
        for _ in range(20):
            t.append(k * DT)
            poses.append(p)
            k += 1
        if i + 1 < len(stops):
            q = stops[i + 1]
            for j in range(1, 10):
                a = j / 10
                t.append(k * DT)
                poses.append(tuple(p[d] + a * (q[d] - p[d]) for d in range(3)))
                k += 1
    return np.array(t, dtype=np.int64), np.array(poses)


def _track(t: np.ndarray, gt: np.ndarray, offset_m: float, heading_rad: float) -> PoseTrack:
    """Every estimate `offset_m` east and `heading_rad` left of the truth, with +-2 mm and
    +-0.001 rad alternating jitter; no pose in the first frame."""
    out: list[PoseEstimate | NoPose] = [NoPose(int(t[0]), "identifying")]
    for k in range(1, len(t)):
        s = 1 if k % 2 else -1
        x, y, th = gt[k]
        out.append(
            PoseEstimate(int(t[k]), x + offset_m + s * 0.002, y, th + heading_rad + s * 0.001,
                         np.eye(3) * 1e-6, "landmark", (1, 2))
        )  # fmt: skip
    return track_from_estimates(out)


def test_stops_error_heading_and_jitter_are_measured_as_constructed() -> None:
    t, gt = _truth()
    assert [(a, b) for a, b in parked_stops(t, gt)] == [(0, 20), (29, 49), (58, 78)]
    result = sec_v(_track(t, gt, 0.01, 0.002), t, gt, settle_s=0.25)
    f = result.figures
    assert f["stops"] == 3
    # the mean of the alternating jitter is within 2 mm / 15 frames of the offset
    np.testing.assert_allclose(f["mean_cm"], 1.0, atol=0.03)
    np.testing.assert_allclose(f["max_cm"], 1.0, atol=0.03)
    np.testing.assert_allclose(f["heading_deg"], math.degrees(0.002), atol=0.01)
    np.testing.assert_allclose(f["jitter_cm"], 0.2, atol=0.02)
    np.testing.assert_allclose(f["jitter_deg"], math.degrees(0.001), atol=0.01)
    headings = [s.true[2] for s in result.stops]
    np.testing.assert_allclose(headings, [0.0, math.pi / 2, math.pi])


def test_error_stats_count_frames_without_a_pose() -> None:
    t, gt = _truth()
    stats = error_stats(_track(t, gt, 0.01, 0.0), t, gt)
    assert stats["frames"] == len(t)
    np.testing.assert_allclose(stats["posed"], (len(t) - 1) / len(t))
    np.testing.assert_allclose(stats["first_fix_s"], 0.1)
    assert stats["landmark"] == pytest.approx((len(t) - 1) / len(t))
    np.testing.assert_allclose(stats["max_cm"], 1.2, atol=1e-9)  # offset + jitter, same sign


def test_table_stands_beside_the_paper() -> None:
    t, gt = _truth()
    text = sec_v_table(sec_v(_track(t, gt, 0.01, 0.0), t, gt))
    lines = text.splitlines()
    assert lines[0] == "Sec. V figures over 3 parked stops"
    row = next(line for line in lines if line.strip().startswith("mean position error"))
    assert row.split()[-2:] == ["1.000", f"{PAPER['mean_cm']:.2f}"]


def test_read_poses_round_trips_replay_output(tmp_path: Path) -> None:
    path = tmp_path / "poses.csv"
    path.write_text(
        "timestamp_ns,x,y,theta,mode,cov_xx,cov_yy,cov_tt,landmarks\n"
        "0,,,,identifying,,,,\n"
        "100,1.5,2.0,0.1,landmark,1e-6,2e-6,3e-7,1 2 3\n"
    )
    track = read_poses(path)
    np.testing.assert_array_equal(track.t_ns, [0, 100])
    assert np.isnan(track.pose[0]).all()
    np.testing.assert_allclose(track.pose[1], [1.5, 2.0, 0.1])
    assert track.landmarks == ((), (1, 2, 3))
    np.testing.assert_allclose(track.covariance_diag[1], [1e-6, 2e-6, 3e-7])
    path.write_text("timestamp_ns,x\n0,1\n")
    with pytest.raises(ValueError, match=r"poses.csv:1: missing columns \['mode', 'theta', 'y'\]"):
        read_poses(path)


def test_jitter_while_parked_from_the_wheels() -> None:
    t = np.arange(0, 40, dtype=np.int64) * DT
    v = np.zeros((40, 2))
    v[10:20] = 0.3  # moving from 1 s to 2 s
    assert odometry_stops(t, v) == [(0, int(9 * DT)), (int(20 * DT), int(39 * DT))]
    gt = np.zeros((40, 3))
    track = _track(t, gt, 0.0, 0.0)
    out = jitter_while_parked(track, odometry_stops(t, v))
    assert len(out) == 2
    # from 0.25 s after each window starts: frames 3-9 (4 at +2 mm, 3 at -2 mm), 23-39 (9, 8):
    # the largest deviation is 2 mm plus the mean's 2/7 and 2/17 mm
    np.testing.assert_allclose([j[2] for j in out], [0.002 + 0.002 / 7, 0.002 + 0.002 / 17])
    np.testing.assert_allclose([j[3] for j in out], [0.001 + 0.001 / 7, 0.001 + 0.001 / 17])
