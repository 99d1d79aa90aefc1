"""The black box on a virtual clock: what a save holds, its triggers, and the disk it uses
over a long run with repeated failures (`live/black_box.py`)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from live.black_box import (
    BlackBox,
    BlackBoxConfig,
    folder_bytes,
    list_black_boxes,
    read_black_box,
)
from localizer.events import FrameObserved, LedsChanged, NoPose, OdometryMeasured, PoseEstimate
from localizer.robot import RobotGeometry
from recording.reader import read_recording
from sim.cameras import wide_angle_camera

CAMERA = wide_angle_camera("pinhole", width=64, height=48)
GEOMETRY = RobotGeometry(wheel_base=0.36, max_speed=1.0)
LANDMARKS = [{"id": 1, "x": 0.0, "y": 0.0, "z": 2.5}, {"id": 2, "x": 1.2, "y": 0.0, "z": 2.5}]
S = 1_000_000_000


class Robot:
    """Feeds a black box as a robot's runner does: 10 Hz frames, 50 Hz odometry, a pose per
    frame (a fix, or lost from `lost_from` on)."""

    def __init__(self, box: BlackBox) -> None:
        self.box, self.t_ns, self.lost = box, 0, False
        self.rng = np.random.default_rng(1)

    def run(self, seconds: float) -> None:
        end = self.t_ns + int(seconds * S)
        while self.t_ns < end:
            self.t_ns += S // 50
            self.box.add_event(OdometryMeasured(self.t_ns, 0.2, 0.2))
            if self.t_ns % (S // 10) == 0:
                image = self.rng.integers(0, 30, (48, 64), dtype=np.uint8)
                self.box.add_event(FrameObserved(self.t_ns, image))
                x = 0.2 * self.t_ns / S
                if self.lost:
                    self.box.add_pose(PoseEstimate(
                        self.t_ns, x, 0.0, 0.0, np.eye(3), "lost", quality=0.0,
                        deviation_m=2.4, reason="kidnapped_suspected", reason_text="moved?",
                    ))  # fmt: skip
                else:
                    self.box.add_pose(PoseEstimate(
                        self.t_ns, x, 0.0, 0.0, np.eye(3) * 1e-6, "landmark", (1, 2),
                        quality=1.0, deviation_m=0.003,
                    ))  # fmt: skip


def box(tmp_path: Path, **kw: float) -> BlackBox:
    cfg = BlackBoxConfig(seconds=5.0, after_s=1.0, min_interval_s=10.0, **kw)  # type: ignore[arg-type]
    return BlackBox("r1", CAMERA, GEOMETRY, lambda: LANDMARKS, tmp_path, cfg)


def test_a_kidnap_saves_the_seconds_around_it_as_an_ordinary_recording(tmp_path: Path) -> None:
    b = box(tmp_path)
    robot = Robot(b)
    b.add_event(LedsChanged(0, all_lit=True))
    robot.run(12.0)
    assert list_black_boxes(tmp_path) == []  # nothing went wrong yet
    robot.lost = True
    t_lost = robot.t_ns + S // 10
    robot.run(2.0)
    b.close()
    [saved] = list_black_boxes(tmp_path, "r1")
    assert (saved.trigger, saved.reason, saved.robot) == ("kidnap", "kidnapped_suspected", "r1")
    assert saved.t_ns == t_lost + S  # after_s of the aftermath
    rec = read_recording(saved.path)
    t_frames = [f.t_ns for f in rec.frames]
    # the window: seconds + after_s back from the save, at 10 Hz
    assert saved.t_ns - S // 10 <= t_frames[-1] <= saved.t_ns
    assert (t_frames[-1] - t_frames[0]) / S == pytest.approx(6.0, abs=0.11)
    assert len(t_frames) == pytest.approx(60, abs=1)
    assert rec.leds[0].all_lit  # the LED state in force before the window
    prior = yaml.safe_load((saved.path / "start_pose.yaml").read_text())
    assert prior["timestamp_ns"] == t_frames[0] and prior["x"] == pytest.approx(0.2 * 7.0, abs=0.03)
    lines = (saved.path / "live_poses.csv").read_text().splitlines()
    assert lines[0].endswith("quality,deviation_m,reason")
    assert sum(line.endswith(",kidnapped_suspected") for line in lines) == 10  # 1 s at 10 Hz


def test_an_operator_click_a_quality_drop_and_the_rate_limit(tmp_path: Path) -> None:
    b = box(tmp_path, quality_below=0.5)
    robot = Robot(b)
    robot.run(3.0)
    path = b.save_now()
    assert read_black_box(path) is not None and read_black_box(path).trigger == "operator"  # type: ignore[union-attr]
    t = robot.t_ns
    b.add_pose(PoseEstimate(t + 1, 0.0, 0.0, 0.0, np.eye(3), "dead_reckoning", quality=0.4,
                            deviation_m=0.1, reason="no_landmark_in_view"))  # fmt: skip
    robot.run(2.0)  # within min_interval_s of the click: not saved
    b.close()
    assert [s.trigger for s in list_black_boxes(tmp_path)] == ["operator"]
    robot.run(9.0)
    b.add_pose(NoPose(robot.t_ns, "lost", reason="lost"))
    robot.run(2.0)
    b.close()
    assert [s.trigger for s in list_black_boxes(tmp_path)] == ["operator", "lost"]


def test_disk_use_stays_under_the_setting_over_half_an_hour_of_failures(tmp_path: Path) -> None:
    other = tmp_path / "r1-20261207T120000"  # an ordinary recording: never removed
    other.mkdir()
    (other / "keep.txt").write_text("x" * 1000)
    one = box(tmp_path / "probe")
    probe = Robot(one)
    probe.run(7.0)
    size = folder_bytes(one.save_now())
    limit = int(3.5 * size)
    b = box(tmp_path, max_bytes=limit)
    robot = Robot(b)
    peak = 0
    for _ in range(30 * 60 // 60):  # a loss every minute for 30 minutes
        robot.lost = False
        robot.run(50.0)
        robot.lost = True
        robot.run(10.0)
        b.close()
        boxes = list_black_boxes(tmp_path)
        peak = max(peak, sum(s.bytes for s in boxes))
    assert len(b.saved) == 30
    assert peak <= limit
    assert len(list_black_boxes(tmp_path)) == 3
    assert list_black_boxes(tmp_path)[-1].path == b.saved[-1]  # the newest kept
    assert (other / "keep.txt").is_file()
