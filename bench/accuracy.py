"""Accuracy of `irloc replay` on simulated scenarios against their ground truth.

For each scenario: `irloc simulate` writes a recording (with groundtruth.csv), `irloc replay`
localizes it, and this compares the two: position error percentiles, heading error, time to
the first fix, misidentifications (a frame whose fix used a landmark not in view, detected as
a fix error larger than `misid_error_m`), and the share of frames per mode.

    .venv/bin/python bench/accuracy.py [--scenarios paper_testbed hostile] [--duration 60]
"""

from __future__ import annotations

import argparse
import csv
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from localizer.geometry import wrap_angle  # noqa: E402
from recording.reader import read_groundtruth  # noqa: E402
from recording.replay_cli import main as replay_main  # noqa: E402
from sim.cli import main as simulate_main  # noqa: E402

SCENARIOS = ("paper_testbed", "paper_floor", "dense_grid_fast", "hostile")
TARGET_P95_M = {"paper_floor": 0.05, "dense_grid_fast": 0.05, "hostile": 0.10}


def read_poses(path: Path) -> list[dict[str, str]]:
    """Rows of a poses.csv."""
    with path.open() as f:
        return list(csv.DictReader(f))


def compare(rec: Path, poses: Path, *, misid_error_m: float = 0.25) -> dict[str, float]:
    """Error statistics of a replay against the recording's groundtruth.csv."""
    t_gt, gt = read_groundtruth(rec)
    rows = read_poses(poses)
    t = np.array([int(r["timestamp_ns"]) for r in rows])
    has = np.array([r["x"] != "" for r in rows])
    x = np.array([float(r["x"]) if r["x"] else np.nan for r in rows])
    y = np.array([float(r["y"]) if r["y"] else np.nan for r in rows])
    th = np.array([float(r["theta"]) if r["theta"] else np.nan for r in rows])
    gx = np.interp(t, t_gt, gt[:, 0])
    gy = np.interp(t, t_gt, gt[:, 1])
    gth = np.interp(t, t_gt, np.unwrap(gt[:, 2]))
    err = np.hypot(x - gx, y - gy)
    herr = np.abs(np.asarray(wrap_angle(th - gth)))
    e = err[has]
    modes = [r["mode"] for r in rows]
    landmark = np.array([m == "landmark" for m in modes])
    fix_err = err[landmark & has]
    first = t[has][0] - t[0] if has.any() else math.inf
    return {
        "frames": float(len(rows)),
        "posed": float(has.mean()),
        "first_fix_s": first * 1e-9,
        "mean_cm": float(np.mean(e)) * 100,
        "p50_cm": float(np.percentile(e, 50)) * 100,
        "p95_cm": float(np.percentile(e, 95)) * 100,
        "max_cm": float(np.max(e)) * 100,
        "heading_mean_deg": float(np.degrees(np.mean(herr[has]))),
        "heading_max_deg": float(np.degrees(np.max(herr[has]))),
        "landmark": float(landmark.mean()),
        "dead_reckoning": float(np.mean([m == "dead_reckoning" for m in modes])),
        "lost": float(np.mean([m == "lost" for m in modes])),
        "misid_frames": float(np.sum(fix_err > misid_error_m)),
    }


def run(name: str, work: Path, duration_s: float | None, seed: int | None) -> dict[str, float]:
    """Simulate, replay and compare one scenario."""
    rec = work / name
    args = [name, str(rec), "--quiet", "--force"]
    if duration_s is not None:
        args += ["--duration", str(duration_s)]
    if seed is not None:
        args += ["--seed", str(seed)]
    if simulate_main(args) != 0:
        raise SystemExit(f"irloc simulate {name} failed")
    poses = work / f"{name}_poses.csv"
    t0 = time.perf_counter()
    if replay_main([str(rec), "--out", str(poses), "--quiet"]) != 0:
        raise SystemExit(f"irloc replay {name} failed")
    stats = compare(rec, poses)
    stats["replay_s"] = time.perf_counter() - t0
    return stats


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenarios", nargs="+", default=list(SCENARIOS))
    parser.add_argument("--duration", type=float, default=None, help="seconds per scenario")
    parser.add_argument("--seed", type=int, default=None)
    parser.add_argument("--keep", type=Path, default=None, help="keep recordings here")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        work = args.keep or Path(tmp)
        work.mkdir(parents=True, exist_ok=True)
        cols = ("frames", "posed", "first_fix_s", "mean_cm", "p50_cm", "p95_cm", "max_cm",
                "heading_mean_deg", "heading_max_deg", "landmark", "dead_reckoning", "lost",
                "misid_frames", "replay_s")  # fmt: skip
        print(f"{'scenario':<16}" + "".join(f"{c:>17}" for c in cols))
        for name in args.scenarios:
            s = run(name, work, args.duration, args.seed)
            print(f"{name:<16}" + "".join(f"{s[c]:>17.3f}" for c in cols), flush=True)
            target = TARGET_P95_M.get(name)
            if target is not None:
                ok = "meets" if s["p95_cm"] < target * 100 else "MISSES"
                print(f"  p95 target < {target * 100:.0f} cm: {ok}")
            print(f"  first fix target < 2 s: {'meets' if s['first_fix_s'] < 2 else 'MISSES'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
