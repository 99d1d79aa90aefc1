"""A poses file (`irloc replay`'s output, a live recording's live_poses.csv) reads back as
the localizer outputs that were written."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from localizer.camera import CameraModel
from localizer.events import NoPose, PoseEstimate
from localizer.robot import RobotGeometry
from recording.layout import LIVE_POSES_FILE
from recording.poses_file import estimates_from_track, format_row
from recording.scoring import read_poses
from recording.writer import RecordingWriter
from sim.cameras import wide_angle_camera

OUTPUTS: list[PoseEstimate | NoPose] = [
    NoPose(1_000, "identifying"),
    PoseEstimate(2_000, 1.25, -0.5, 3.1, np.diag([1e-6, 4e-6, 2.5e-7]), "landmark", (4, 9)),
    PoseEstimate(3_000, 1.3, -0.5, -3.1, np.diag([2e-5, 3e-5, 1e-6]), "dead_reckoning"),
    NoPose(4_000, "lost"),
]


def _camera() -> CameraModel:
    return wide_angle_camera("fisheye")


def test_written_outputs_read_back(tmp_path: Path) -> None:
    with RecordingWriter(
        tmp_path, _camera(), RobotGeometry(0.4), [{"id": 4, "x": 0, "y": 0, "z": 2.5}]
    ) as w:
        for est in OUTPUTS:
            w.add_pose(est)
    path = tmp_path / LIVE_POSES_FILE
    back = estimates_from_track(read_poses(path), source=str(path))
    assert [type(e) for e in back] == [type(e) for e in OUTPUTS]
    for got, want in zip(back, OUTPUTS, strict=True):
        assert (got.t_ns, got.mode) == (want.t_ns, want.mode)
        if isinstance(want, PoseEstimate):
            assert isinstance(got, PoseEstimate)
            np.testing.assert_allclose(
                [got.x, got.y, got.theta], [want.x, want.y, want.theta], atol=1e-6
            )
            np.testing.assert_allclose(got.covariance, want.covariance, rtol=1e-3)
            assert got.landmark_ids == want.landmark_ids


def test_a_simulated_recording_has_no_live_poses(tmp_path: Path) -> None:
    with RecordingWriter(
        tmp_path, _camera(), RobotGeometry(0.4), [{"id": 4, "x": 0, "y": 0, "z": 2.5}]
    ):
        pass
    assert not (tmp_path / LIVE_POSES_FILE).exists()


def test_an_unknown_mode_is_named(tmp_path: Path) -> None:
    path = tmp_path / "poses.csv"
    row = format_row(NoPose(5, "lost")).replace("lost", "asleep")
    path.write_text("timestamp_ns,x,y,theta,mode,cov_xx,cov_yy,cov_tt,landmarks\n" + row + "\n")
    with pytest.raises(ValueError, match="row 1: unknown mode 'asleep'"):
        estimates_from_track(read_poses(path), source=str(path))
