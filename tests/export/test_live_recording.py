"""`irloc export` and `irloc report` on a recording the server wrote from a live robot (the
demo site, recorded once the robot tracks): no ground truth, the site's clock, LED probes of
every robot in leds.csv, the LED state in force at the start, and the robot's live poses
(`live_poses.csv`), which the export takes by default. (Replayed, the localizer does not
identify from such a recording: it identifies from its own LED requests, which a replay
cannot answer; so `--poses replay` gives whatever `irloc replay` gives, checked for
consistency, not for count.)"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader

from export.cli import main as export_main
from recording.reader import read_recording
from recording.replay_cli import main as replay
from recording.scoring import PoseTrack, read_poses
from tests.server.conftest import start_api

pytestmark = pytest.mark.slow
FRAMES = 60


@pytest.fixture(scope="module")
def live_recording(tmp_path_factory: pytest.TempPathFactory) -> Path:
    site = start_api(tmp_path_factory.mktemp("live"))
    api = next(site)
    try:
        c, h = api.client, api.h("operator")
        robot = api.services.robots.get("r1")
        t_end = time.monotonic() + 60
        while robot.mode != "landmark" and time.monotonic() < t_end:
            time.sleep(0.1)
        assert robot.mode == "landmark"
        assert c.post("/api/v1/robots/r1/recording/start", headers=h).status_code == 200
        frames0, t_end = robot.frames, time.monotonic() + 90
        while robot.frames < frames0 + FRAMES and time.monotonic() < t_end:
            time.sleep(0.1)
        r = c.post("/api/v1/robots/r1/recording/stop", headers=h)
        return Path(r.json()["path"])
    finally:
        site.close()


@pytest.fixture(scope="module")
def replayed(live_recording: Path, tmp_path_factory: pytest.TempPathFactory) -> PoseTrack:
    out = tmp_path_factory.mktemp("live_poses") / "poses.csv"
    assert replay([str(live_recording), "--out", str(out), "--quiet"]) == 0
    return read_poses(out)


def _counts(out: Path) -> dict[str, int]:
    with out.open("rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None and summary.statistics is not None
    return {
        c.topic: summary.statistics.channel_message_counts[cid]
        for cid, c in summary.channels.items()
    }


def test_the_recording_holds_the_live_poses_and_the_leds_in_force(live_recording: Path) -> None:
    rec = read_recording(live_recording)
    assert rec.leds and rec.leds[0].t_ns <= rec.frames[0].t_ns  # the state at the start
    live = read_poses(live_recording / "live_poses.csv")
    assert [int(t) for t in live.t_ns] == [f.t_ns for f in rec.frames]
    assert float(np.mean(np.array(live.mode) == "landmark")) >= 0.9
    assert all(ids for ids, m in zip(live.landmarks, live.mode, strict=True) if m == "landmark")


def test_replayed_export_takes_the_replays_poses(
    live_recording: Path, replayed: PoseTrack, tmp_path: Path
) -> None:
    out = tmp_path / "replayed.mcap"
    args = [str(live_recording), "--mcap", str(out), "--poses", "replay", "--quiet"]
    assert export_main(args) == 0
    assert _counts(out).get("/irloc/pose", 0) == int(replayed.has_pose.sum())


@pytest.mark.parametrize("profile", ["foxglove", "ros2"])
def test_live_recording_exports(live_recording: Path, tmp_path: Path, profile: str) -> None:
    rec = read_recording(live_recording)
    assert len(rec.frames) >= FRAMES - 5
    out = tmp_path / "live.mcap"
    args = [str(live_recording), "--mcap", str(out), "--profile", profile, "--quiet"]
    assert export_main(args) == 0
    counts = _counts(out)
    assert counts["/cam0/image/compressed"] == len(rec.frames)
    assert counts["/tf"] == len(rec.frames)
    assert "/groundtruth" not in counts
    live = read_poses(live_recording / "live_poses.csv")
    assert counts["/irloc/pose"] == int(live.has_pose.sum()) > 0
    assert counts["/irloc/mode"] >= 1
    start = (
        min(rec.frames[0].t_ns, int(rec.odom_t_ns[0])) if len(rec.odom_t_ns) else rec.frames[0].t_ns
    )
    changes = [e for e in rec.leds if start < e.t_ns <= rec.frames[-1].t_ns]
    assert counts["/landmarks"] == 1 + len(changes)  # the start, then every LED change
    assert counts["/odom"] == int(np.sum(rec.odom_t_ns <= rec.frames[-1].t_ns))
