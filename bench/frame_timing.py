"""The localizer's per-frame time on a slow drive past three landmarks, and the same
measurement run against another checkout's localizer.

`render_drive` renders the frames once (this tree's simulator); `time_localizer` feeds them,
with three odometry samples per frame interval, to a fresh `Localizer` `runs` times and
keeps each frame's fastest run (the localizer is deterministic, so every run does the same
work; the fastest is the one other processes disturbed least). It times, in the thread's
CPU time:

- `frame`: `handle(FrameObserved)`, from the frame in to its pose out: the latency the
  camera loop waits for;
- `interval`: the frame's interval in all: its odometry samples and the frame (and so also
  the learning a fused frame leaves for after its pose is out, done on the next event);
- full-frame spot detection and a plain copy of the same frame, for scale.

`time_other_tree` runs `time_localizer` from this file in a fresh process whose imports
resolve to another checkout's `localizer` (its `Localizer`, events and camera), on the same
frames: both trees are measured by the same code on the same input. Only names that every
tree since November has are imported here.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

LANDMARKS = [[0.0, 0.0, 2.5], [1.2, 0.0, 2.5], [0.6, 1.0392, 2.5]]
RADIUS_M, TURN_RAD_S, HALF_TRACK_M = 0.3, 0.5, 0.18  # a circle at 0.15 m/s


def _pose(t: float) -> tuple[float, float, float]:
    w, r = TURN_RAD_S, RADIUS_M
    return 0.6 + r * math.sin(w * t), 0.3 - r * math.cos(w * t), w * t


def render_drive(width: int, height: int, frames: int) -> np.ndarray:
    """The drive's frames at 30 Hz, shape (frames, height, width), uint8."""
    from localizer.geometry import T_world_body_from_pose
    from sim.cameras import wide_angle_camera
    from sim.render import render_frame

    cam = wide_angle_camera("pinhole", width=width, height=height)
    rng = np.random.default_rng(0)
    positions = np.array(LANDMARKS)
    return np.stack(
        [
            render_frame(
                cam, T_world_body_from_pose(*_pose(k / 30)), positions, np.ones(3), rng=rng
            )
            for k in range(frames)
        ]
    )


def time_localizer(images: np.ndarray, runs: int = 3) -> dict[str, float]:
    """Per-frame times (microseconds): median and p99 over the frames tracked in every run
    of each frame's fastest run (module docstring)."""
    from localizer.events import FrameObserved, OdometryMeasured
    from localizer.landmark_map import LandmarkMap
    from localizer.localizer import Localizer
    from localizer.robot import RobotGeometry
    from localizer.spots import DetectionConfig, detect_spots
    from sim.cameras import wide_angle_camera

    n, height, width = images.shape
    cam = wide_angle_camera("pinhole", width=width, height=height)
    lm = LandmarkMap(np.array([1, 2, 3]), np.array(LANDMARKS))
    v = RADIUS_M * TURN_RAD_S
    vl, vr = v - TURN_RAD_S * HALF_TRACK_M, v + TURN_RAD_S * HALF_TRACK_M
    frame = np.full((runs, n), np.inf)
    interval = np.full((runs, n), np.inf)
    full, copy = np.full((runs, n), np.inf), np.full((runs, n), np.inf)
    cfg = DetectionConfig()
    for run in range(runs):
        loc = Localizer(cam, lm, RobotGeometry(0.36, 1.0))
        loc.set_initial_pose(0.6, 0.0, 0.0, 0)  # all LEDs lit, no sweep: start from a prior
        for k in range(n):
            img = images[k]
            t_ns = int(k * 1e9 / 30)
            odo = [OdometryMeasured(t_ns - int(j * 1e7), vl, vr) for j in (2, 1, 0)]
            t0 = time.thread_time_ns()
            for o in odo:
                loc.handle(o)
            t1 = time.thread_time_ns()
            loc.handle(FrameObserved(t_ns, img))
            t2 = time.thread_time_ns()
            detect_spots(img, cfg)
            t3 = time.thread_time_ns()
            img.copy()
            t4 = time.thread_time_ns()
            if loc.mode == "landmark":
                frame[run, k], interval[run, k] = t2 - t1, t2 - t0
            full[run, k], copy[run, k] = t3 - t2, t4 - t3
    tracked = np.all(np.isfinite(frame), axis=0)  # frames tracked in every run

    def q(a: np.ndarray, p: float) -> float:
        return float(np.percentile(a.min(axis=0), p)) / 1000

    return {
        "frame_med_us": q(frame[:, tracked], 50),
        "frame_p99_us": q(frame[:, tracked], 99),
        "interval_med_us": q(interval[:, tracked], 50),
        "interval_p99_us": q(interval[:, tracked], 99),
        "full_med_us": q(full, 50),
        "full_p99_us": q(full, 99),
        "copy_med_us": q(copy, 50),
        "copy_p99_us": q(copy, 99),
        "tracked_frames": float(np.count_nonzero(tracked)),
    }


_CHILD = """
import importlib.util, json, sys
import numpy as np
sys.path.insert(0, sys.argv[2])
import cv2
cv2.setNumThreads(1)
spec = importlib.util.spec_from_file_location("frame_timing_here", sys.argv[1])
mod = importlib.util.module_from_spec(spec)
spec.loader.exec_module(mod)
print(json.dumps(mod.time_localizer(np.load(sys.argv[3]))))
"""


def time_other_tree(root: Path, images_npy: Path) -> dict[str, float]:
    """`time_localizer` on the frames saved in `images_npy`, in a fresh process whose
    `localizer` (and camera factory) is the checkout at `root`'s."""
    run = subprocess.run(
        [sys.executable, "-c", _CHILD, __file__, str(root), str(images_npy)],
        capture_output=True,
        text=True,
        check=False,
    )
    if run.returncode != 0:
        raise RuntimeError(f"timing in {root} failed:\n{run.stderr}")
    out: dict[str, float] = json.loads(run.stdout.splitlines()[-1])
    return out


def alternate(
    here: Path, other: Path, images: np.ndarray, rounds: int
) -> tuple[list[dict[str, float]], list[dict[str, float]]]:
    """`time_other_tree` of this tree and of `other`, alternately (`rounds` each), on the
    same frames, so that both see the same machine load."""
    mine: list[dict[str, float]] = []
    theirs: list[dict[str, float]] = []
    with tempfile.TemporaryDirectory() as tmp:
        npy = Path(tmp) / "frames.npy"
        np.save(npy, images)
        for _ in range(rounds):
            mine.append(time_other_tree(here, npy))
            theirs.append(time_other_tree(other, npy))
    return mine, theirs
