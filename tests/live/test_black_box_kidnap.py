"""A kidnap on the demo site: the robot's runner (as the live site runs it) saves its black
box, listed among the robot's recordings with its trigger, and `irloc replay` of that box
goes through the same loss."""

from __future__ import annotations

import io
from importlib import resources
from pathlib import Path

import cv2
import yaml

from live.black_box import BlackBox, BlackBoxConfig, list_black_boxes
from live.robots import RobotRunner, make_localizer
from localizer.events import FrameObserved, NoPose, PoseEstimate, RelocalizeRequested
from recording.reader import FrameEntry, iter_timeline, read_groundtruth, read_recording
from recording.replay_cli import replay
from sim.scenario import load_scenario
from store.recording_catalog import RecordingCatalog

S = 1_000_000_000


def demo_with_a_kidnap(tmp_path: Path) -> Path:
    """The demo site (its hall, landmarks, lamps, glint) with one robot that drives along the
    hall, is lifted and put down 2.6 m away, turned, and drives on."""
    data = yaml.safe_load((resources.files("sim.scenarios") / "demo.yaml").read_text())
    data["robots"] = [{
        "name": "r1", "start": [0.6, 0.6, 0.0], "max_speed_mps": 1.0,
        "wheel_radius_error": [0.003, -0.002], "wheel_base_error": 0.01,
        "route": {"speed_mps": 0.6, "steps": [
            {"goto": [3.0, 0.6]},
            {"kidnap": {"to": [2.4, 3.0, 120.0], "carry_s": 1.5, "lift_m": 0.3}},
            {"wait": 1.0},
            {"goto": [0.6, 3.0]},
        ]},
    }]  # fmt: skip
    path = tmp_path / "demo_kidnap.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


def test_a_kidnap_on_the_demo_site_saves_a_black_box_whose_replay_is_lost(
    tmp_path: Path,
) -> None:
    from irloc.simulated_recording import simulate_recording

    src = tmp_path / "drive"
    simulate_recording(load_scenario(demo_with_a_kidnap(tmp_path)), src, duration_s=10.5)
    rec = read_recording(src)
    runner = RobotRunner("r1", rec.camera, rec.robot,
                         make_localizer(rec.camera, rec.landmark_map, rec.robot),
                         publish=lambda u: None, request_leds=lambda r, q: None)  # fmt: skip
    root = tmp_path / "recordings"
    records = list(rec.landmark_records)
    runner.black_box = BlackBox("r1", rec.camera, rec.robot, lambda: records, root,
                                BlackBoxConfig(seconds=8.0, after_s=1.0))  # fmt: skip
    outputs: list[PoseEstimate | NoPose] = []
    runner.on_mode_change = lambda name, old, new: None
    tap = runner.black_box.add_pose
    runner.black_box.add_pose = lambda out: (outputs.append(out), tap(out))[1]  # type: ignore[method-assign]
    t_gt, gt = read_groundtruth(src)  # the dock it starts at, known to 30 cm
    dock = (float(gt[0, 0]), float(gt[0, 1]), float(gt[0, 2]))
    runner.handle(RelocalizeRequested(int(t_gt[0]), near=dock, radius_m=0.3))
    for item in iter_timeline(rec):
        if isinstance(item, FrameEntry):
            item = FrameObserved(item.t_ns, cv2.imread(str(item.path), cv2.IMREAD_GRAYSCALE))
        runner.handle(item)
    runner.black_box.close()

    live_lost = [o for o in outputs if o.mode == "lost"]
    assert any(o.mode == "landmark" for o in outputs[: len(outputs) // 3])  # it was localized
    assert live_lost, "the kidnap was not noticed"
    [saved] = list_black_boxes(root, "r1")
    assert saved.trigger in ("kidnap", "lost") and saved.reason == live_lost[0].reason
    [listed] = RecordingCatalog(root, set).list("r1")  # among the robot's recordings
    assert listed.name == saved.path.name and listed.trigger == f"black_box_{saved.trigger}"

    estimates: list[PoseEstimate | NoPose] = []
    replay(saved.path, io.StringIO(), threads=1, estimates=estimates)
    assert any(o.mode == "landmark" for o in estimates)  # localized from the box's start pose
    replay_lost = [o for o in estimates if o.mode == "lost"]
    assert replay_lost, "the replay of the black box did not reproduce the loss"
    assert replay_lost[0].reason == live_lost[0].reason
    assert abs(replay_lost[0].t_ns - live_lost[0].t_ns) <= 1 * S
