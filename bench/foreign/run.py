"""Replay the independent generator's recordings (`bench/foreign/generate.py`) and score
them: the localizer on data our own simulator never shaped.

    .venv/bin/python bench/foreign/run.py [--only CASE ...] [--seconds S] [--seed N]
        [--work DIR]

Prints per case: p95 / max error (cm), heading mean (deg), the share of frames in landmark
mode and lost, first fix (s), gross fixes (frames in landmark mode more than 20 cm off:
a wrong identification or a wrong pair) and, for a kidnapped robot, the recovery (s from
being put down to the first fix within 10 cm; inf: never). Recordings are cached in the
work folder.
"""

from __future__ import annotations

import argparse
import hashlib
import io
import math
import shutil
import sys
import time
from pathlib import Path

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from bench.foreign.cases import CASES
from bench.foreign.generate import generate
from localizer.events import NoPose, PoseEstimate
from recording.reader import read_groundtruth
from recording.replay_cli import replay
from recording.scoring import error_stats, errors, track_from_estimates

HERE = Path(__file__).resolve().parent


def recording_for_case(name: str, work: Path, seconds: float | None, seed: int) -> Path:
    """The case's recording in the work folder (generated unless cached)."""
    case = CASES[name]
    dur = seconds or case.seconds
    code = hashlib.sha256(
        b"".join((HERE / f).read_bytes() for f in ("generate.py", "cases.py"))
    ).hexdigest()[:10]
    rec = work / f"{name}-s{seed}-{dur:g}-{code}"
    if not (rec / "groundtruth.csv").is_file():
        shutil.rmtree(rec, ignore_errors=True)
        tmp = rec.with_name(rec.name + ".part")
        shutil.rmtree(tmp, ignore_errors=True)
        generate(case, tmp, dur, seed)
        tmp.rename(rec)
    return rec


def run_case(name: str, work: Path, seconds: float | None, seed: int) -> dict[str, float]:
    case = CASES[name]
    rec = recording_for_case(name, work, seconds, seed)
    estimates: list[PoseEstimate | NoPose] = []
    t0 = time.perf_counter()
    replay(rec, io.StringIO(), estimates=estimates)
    took = time.perf_counter() - t0
    track = track_from_estimates(estimates)
    t_gt, gt = read_groundtruth(rec)
    stats = error_stats(track, t_gt, gt)
    err, _ = errors(track, t_gt, gt)
    landmark = np.array(track.mode) == "landmark"
    stats["gross"] = float(np.sum(landmark & track.has_pose & (err > 0.20)))
    stats["recovery_s"] = math.nan
    if case.kidnap_s is not None:  # back in landmark mode within 10 cm of the truth
        t_rel = (np.asarray(track.t_ns) - case.epoch_ns) * 1e-9
        back = np.flatnonzero((t_rel > case.kidnap_s) & landmark & track.has_pose & (err < 0.10))
        stats["recovery_s"] = float(t_rel[back[0]] - case.kidnap_s) if len(back) else math.inf
    stats["replay_s"] = took
    return stats


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--only", action="append", choices=sorted(CASES), default=None)
    p.add_argument("--seconds", type=float, default=None)
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--work", type=Path, default=Path("/tmp/irloc-foreign"))
    a = p.parse_args(argv)
    a.work.mkdir(parents=True, exist_ok=True)
    print(
        "| case | p95 cm | max cm | hdg mean deg | landmark % | lost % | first fix s | gross "
        "| recovery s |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    for name in a.only or list(CASES):
        s = run_case(name, a.work, a.seconds, a.seed)
        rec_s = "-" if math.isnan(s["recovery_s"]) else f"{s['recovery_s']:.1f}"
        print(
            f"| {name} | {s['p95_cm']:.1f} | {s['max_cm']:.1f} | {s['heading_mean_deg']:.3f} | "
            f"{100 * s['landmark']:.0f} | {100 * s['lost']:.0f} | {s['first_fix_s']:.1f} | "
            f"{s['gross']:.0f} | {rec_s} |",
            flush=True,
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
