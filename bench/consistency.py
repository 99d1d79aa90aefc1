"""Consistency of the published covariance: how often the truth lies where the pose says.

Every replay run of the robustness matrix (`bench/robustness.py`, held-out runs included) and
every foreign recording (`bench/foreign`) is localized as `irloc replay` does it; each pose
with truth is scored by its normalised estimation error squared (NEES) against the
covariance it was published with:

- position: e^T P_xy^-1 e, within the 95 % ellipse when <= 5.991 (chi-square, 2 dof; the
  "2-sigma" ellipse of a 2-D error: the one that should hold 95 % of them);
- heading: e_theta^2 / P_tt, within 2 sigma when <= 4 (95.4 % for a consistent estimate);
- the 95 % radius: |e| <= `deviation_m` (when the poses carry it).

Prints one markdown table per group (matrix, held out, foreign) with a row per mode, and
optionally writes the per-frame figures (`--frames out.npz`: errors, covariances, modes,
for fitting an inflation model) and the table's figures (`--json`). Frames while a
kidnapper carries the robot (matrix runs) are left out; the live-loop runs (`loop: leds`)
have no recording and are not covered.

    .venv/bin/python bench/consistency.py [--only GLOB] [--jobs 2] [--json out.json]
        [--frames out.npz] [--work DIR] [--foreign-work DIR] [--no-foreign]
"""

from __future__ import annotations

import argparse
import fnmatch
import io
import json
import math
import multiprocessing
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from bench.foreign.cases import CASES  # noqa: E402
from bench.foreign.run import recording_for_case  # noqa: E402
from bench.robustness import MATRIX_FILES, load_matrix, recording_for  # noqa: E402
from localizer.events import MODES, NoPose, PoseEstimate  # noqa: E402
from localizer.geometry import wrap_angle  # noqa: E402
from localizer.types import FloatArray  # noqa: E402
from recording.reader import read_groundtruth  # noqa: E402
from recording.replay_cli import replay  # noqa: E402

CHI2_2DOF_95 = 5.991
"""The 95 % point of chi-square with 2 degrees of freedom."""
GROUPS = ("matrix", "held_out", "foreign")


@dataclass(frozen=True)
class Job:
    """One recording to localize and score."""

    name: str
    group: str
    kind: str  # "matrix" | "foreign"
    work: Path
    seconds: float | None = None


def frames_of(
    estimates: list[PoseEstimate | NoPose],
    t_gt: npt.NDArray[np.int64],
    gt: FloatArray,
    kidnaps: list[tuple[int, int]],
) -> dict[str, Any]:
    """Per-frame errors and covariances of the poses with truth (arrays, one row a frame)."""
    poses = [
        e
        for e in estimates
        if isinstance(e, PoseEstimate)
        and t_gt[0] <= e.t_ns <= t_gt[-1]
        and not any(a <= e.t_ns <= b for a, b in kidnaps)
    ]
    t = np.array([e.t_ns for e in poses], dtype=np.int64)
    unwrapped = np.unwrap(gt[:, 2])
    truth = (
        np.column_stack(
            [np.interp(t, t_gt, gt[:, j]) for j in (0, 1)] + [np.interp(t, t_gt, unwrapped)]
        )
        if len(t)
        else np.zeros((0, 3))
    )
    est = np.array([(e.x, e.y, e.theta) for e in poses], dtype=np.float64).reshape(-1, 3)
    err = est - truth
    err[:, 2] = wrap_angle(err[:, 2]) if len(err) else err[:, 2]
    cov = np.array([e.covariance for e in poses], dtype=np.float64).reshape(-1, 3, 3)
    dev = np.array([getattr(e, "deviation_m", math.nan) for e in poses], dtype=np.float64)
    return {
        "t_ns": t,
        "mode": np.array([MODES.index(e.mode) for e in poses], dtype=np.int8),
        "landmarks": np.array([len(e.landmark_ids) for e in poses], dtype=np.int16),
        "expected": np.array([len(e.expected_ids) for e in poses], dtype=np.int16),
        "err": err,
        "cov": cov,
        "deviation_m": dev,
    }


def run_job(job: Job) -> tuple[Job, dict[str, Any]]:
    """Localize one recording and return its frames (a worker process's job)."""
    kidnaps: list[tuple[int, int]] = []
    if job.kind == "matrix":
        runs = {
            r.name: r
            for f, h in zip(MATRIX_FILES, (False, True), strict=True)
            for r in load_matrix(f, held_out=h)
        }
        run = runs[job.name]
        rec, kidnaps = recording_for(run, run.build(), job.work, run.duration_s)
    else:
        rec = recording_for_case(job.name, job.work, job.seconds, 1)
    estimates: list[PoseEstimate | NoPose] = []
    replay(rec, io.StringIO(), threads=1, estimates=estimates)
    t_gt, gt = read_groundtruth(rec)
    return job, frames_of(estimates, t_gt, gt, kidnaps)


def shares(frames: dict[str, Any], mask: npt.NDArray[np.bool_]) -> dict[str, float]:
    """The consistency figures of the frames under `mask`."""
    err, cov = frames["err"][mask], frames["cov"][mask]
    n = int(mask.sum())
    if n == 0:
        return {"frames": 0}
    P = cov[:, :2, :2]
    e = err[:, :2]
    det = P[:, 0, 0] * P[:, 1, 1] - P[:, 0, 1] ** 2
    ok = det > 0
    inv = np.zeros_like(P)
    inv[ok, 0, 0] = P[ok, 1, 1] / det[ok]
    inv[ok, 1, 1] = P[ok, 0, 0] / det[ok]
    inv[ok, 0, 1] = inv[ok, 1, 0] = -P[ok, 0, 1] / det[ok]
    nees_pos = np.where(ok, np.einsum("ni,nij,nj->n", e, inv, e), np.inf)
    var_t = cov[:, 2, 2]
    nees_th = np.where(var_t > 0, err[:, 2] ** 2 / np.where(var_t > 0, var_t, 1.0), np.inf)
    dev = frames["deviation_m"][mask]
    dist = np.hypot(e[:, 0], e[:, 1])
    out = {
        "frames": n,
        "pos_in_95": float(np.mean(nees_pos <= CHI2_2DOF_95)),
        "hdg_in_2sigma": float(np.mean(nees_th <= 4.0)),
        "pos_nees_median": float(np.median(nees_pos)),
        "hdg_nees_median": float(np.median(nees_th)),
        "err_p95_cm": float(100 * np.percentile(dist, 95)),
    }
    if np.all(np.isfinite(dev)):
        out["in_deviation"] = float(np.mean(dist <= dev))
        out["deviation_median_cm"] = float(100 * np.median(dev))
    return out


def summarize(per_job: list[tuple[Job, dict[str, Any]]]) -> dict[str, dict[str, dict[str, float]]]:
    """group -> mode (and "all") -> figures."""
    out: dict[str, dict[str, dict[str, float]]] = {}
    for group in GROUPS:
        jobs = [f for j, f in per_job if j.group == group]
        if not jobs:
            continue
        merged = {k: np.concatenate([f[k] for f in jobs]) for k in jobs[0]}
        rows: dict[str, dict[str, float]] = {
            m: shares(merged, merged["mode"] == k) for k, m in enumerate(MODES)
        }
        rows["all"] = shares(merged, np.ones(len(merged["mode"]), dtype=bool))
        out[group] = rows
    return out


def table(summary: dict[str, dict[str, dict[str, float]]]) -> str:
    """The figures as markdown."""
    head = (
        "group",
        "mode",
        "frames",
        "pos in 95 % ellipse",
        "hdg in 2 sigma",
        "pos NEES median",
        "hdg NEES median",
        "err p95 cm",
        "in deviation_m",
        "deviation_m median cm",
    )
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for group, rows in summary.items():
        for mode, r in rows.items():
            if not r.get("frames"):
                continue
            dev = "deviation_median_cm"
            cells = [
                group,
                mode,
                str(r["frames"]),
                f"{100 * r['pos_in_95']:.1f} %",
                f"{100 * r['hdg_in_2sigma']:.1f} %",
                f"{r['pos_nees_median']:.2f}",
                f"{r['hdg_nees_median']:.2f}",
                f"{r['err_p95_cm']:.1f}",
                f"{100 * r['in_deviation']:.1f} %" if "in_deviation" in r else "-",
                f"{r[dev]:.1f}" if dev in r else "-",
            ]
            lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def jobs_from(args: argparse.Namespace) -> list[Job]:
    jobs: list[Job] = []
    for path, held in zip(MATRIX_FILES, (False, True), strict=True):
        for run in load_matrix(path, held_out=held):
            if run.loop == "replay":
                group = "held_out" if held else "matrix"
                jobs.append(Job(run.name, group, "matrix", args.work))
    if args.foreign:
        jobs += [Job(name, "foreign", "foreign", args.foreign_work) for name in CASES]
    if args.only:
        jobs = [j for j in jobs if any(fnmatch.fnmatch(j.name, p) for p in args.only)]
    return jobs


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--only", action="append", default=[], metavar="GLOB")
    p.add_argument("--jobs", type=int, default=2, help="worker processes (default 2)")
    p.add_argument("--json", type=Path, default=None, help="write the table's figures here")
    p.add_argument("--frames", type=Path, default=None, help="write per-frame figures (.npz)")
    p.add_argument(
        "--work",
        type=Path,
        default=Path(tempfile.gettempdir()) / "irloc-robustness",
        help="the robustness matrix's recordings (simulated when missing)",
    )
    p.add_argument(
        "--foreign-work",
        type=Path,
        default=Path("/tmp/irloc-foreign"),
        help="the foreign recordings (generated when missing)",
    )
    p.add_argument("--foreign", action=argparse.BooleanOptionalAction, default=True)
    args = p.parse_args(argv)
    jobs = jobs_from(args)
    if not jobs:
        print("no recording matches", file=sys.stderr)
        return 1
    args.work.mkdir(parents=True, exist_ok=True)
    args.foreign_work.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    done: list[tuple[Job, dict[str, Any]]] = []
    if args.jobs > 1 and len(jobs) > 1:
        with multiprocessing.get_context("spawn").Pool(min(args.jobs, len(jobs))) as pool:
            for item in pool.imap(run_job, jobs):
                done.append(item)
                print(f"  {item[0].name}: {len(item[1]['t_ns'])} poses", file=sys.stderr)
    else:
        done = [run_job(j) for j in jobs]
    summary = summarize(done)
    print(table(summary))
    print(f"\n{len(done)} recordings in {time.perf_counter() - t0:.0f} s (wall)")
    if args.json is not None:
        args.json.write_text(json.dumps(summary, indent=1))
    if args.frames is not None:
        keys = list(done[0][1])
        arrays = {k: np.concatenate([f[k] for _, f in done]) for k in keys}
        arrays["run"] = np.concatenate(
            [np.full(len(f["t_ns"]), i, dtype=np.int16) for i, (_, f) in enumerate(done)]
        )
        arrays["group"] = np.array([GROUPS.index(j.group) for j, _ in done], dtype=np.int8)
        arrays["names"] = np.array([j.name for j, _ in done])
        np.savez_compressed(args.frames, **arrays)  # type: ignore[arg-type]
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
