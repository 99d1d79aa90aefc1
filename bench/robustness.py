"""The robustness matrix: the localizer in buildings it was never tuned on.

Each run of the matrix (`bench/robustness/matrix.yaml`, and the held-out runs in
`bench/robustness/held_out/matrix.yaml`) names a scenario file and the factor levels it
covers (lens, calibration error, mounting, layout, motion, disturbances). A run is either

- `replay`: the scenario is simulated to a recording
  (`irloc.simulated_recording.simulate_recording`, cached in the work folder), localized
  exactly as `irloc replay` does it
  (`recording.replay_cli.replay`: the LEDs are what the recording says, no LED control), or
- `leds`: the live site loop with LED control (`bench/robustness_live.py`: the live site,
  the RF gateway on the simulated radio and the server's LED coordinator, on a virtual
  clock, faster than real time),

then scored against the simulator's truth (`bench/robustness_score.py`). It prints one
markdown table and writes the figures as JSON.

    .venv/bin/python bench/robustness.py [--only 'grid40*'] [--quick] [--jobs 2]
        [--held-out | --no-held-out] [--json out.json] [--baseline before.json]
        [--work DIR] [--fresh]
"""

from __future__ import annotations

import argparse
import dataclasses
import fnmatch
import hashlib
import json
import math
import multiprocessing
import os
import shutil
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from bench.robustness_score import FrameResult, Score, SiteTruth, score  # noqa: E402
from irloc.simulated_recording import simulate_recording  # noqa: E402
from recording.reader import read_groundtruth  # noqa: E402
from recording.replay_cli import replay  # noqa: E402
from sim.build import RobotRig  # noqa: E402
from sim.cameras import CALIBRATION_LEVELS, LENSES, Lens  # noqa: E402
from sim.fields import Node  # noqa: E402
from sim.offline import recording_site  # noqa: E402
from sim.scenario import Scenario, load_scenario  # noqa: E402
from sim.world import World  # noqa: E402

MATRIX_DIR = ROOT / "bench" / "robustness"
MATRIX_FILES = (MATRIX_DIR / "matrix.yaml", MATRIX_DIR / "held_out" / "matrix.yaml")
QUICK_S = 20.0
TARGET_KEYS = ("p95_cm", "heading_mean_deg", "landmark_min", "misidentified", "recover_s")


@dataclass(frozen=True)
class Run:
    """One run of the matrix (see `bench/robustness/matrix.yaml` for the fields)."""

    name: str
    scenario: Path
    covers: str
    loop: str = "replay"
    robot: str | None = None
    lens: Lens | None = None
    calibration: str | None = None
    seed: int | None = None
    duration_s: float = 30.0
    held_out: bool = False
    targets: dict[str, float] = field(default_factory=dict)

    def build(self) -> Scenario:
        """The scenario with this run's lens and calibration error."""
        sc = load_scenario(self.scenario)
        if self.lens is not None:
            sc = sc.with_lens(self.lens)
        if self.calibration is not None:
            sc = sc.with_calibration(CALIBRATION_LEVELS[self.calibration])
        return sc


def load_matrix(path: Path, *, held_out: bool) -> list[Run]:
    """The runs of one matrix file (scenario paths relative to it).

    Raises:
        ValueError: naming the file and the field.
    """
    doc = Node(yaml.safe_load(path.read_text(encoding="utf-8")), "", str(path)).mapping(("runs",))
    runs = []
    keys = (
        "name",
        "scenario",
        "covers",
        "loop",
        "robot",
        "lens",
        "calibration",
        "seed",
        "duration_s",
        "targets",
    )
    for n in doc.child("runs", required=True).items():
        n.mapping(keys)
        scenario = path.parent / n.string("scenario")
        if not scenario.is_file():
            raise n.child("scenario").error(f"no such file {scenario}")
        t = n.child("targets", {}).mapping(TARGET_KEYS)
        runs.append(
            Run(
                name=n.string("name"),
                scenario=scenario,
                covers=n.string("covers"),
                loop=n.string("loop", "replay", choices=("replay", "leds")),
                robot=n.string("robot", "") or None,
                lens=n.string("lens", "", choices=("", *LENSES)) or None,  # type: ignore[arg-type]
                calibration=n.string("calibration", "", choices=("", *CALIBRATION_LEVELS)) or None,
                seed=n.integer("seed") if n.has("seed") else None,
                duration_s=n.number("duration_s", 30.0, low=1.0, high=600.0),
                held_out=held_out,
                targets={k: t.number(k) for k in TARGET_KEYS if t.has(k)},
            )
        )
    return runs


def site_truth(world: World, rig: RobotRig) -> SiteTruth:
    """The truth the scorer checks identifications against (see `SiteTruth`)."""
    lms = [
        lm
        for lm in sorted(world.landmarks.values(), key=lambda lm: lm.id)
        if not lm.led_dead or lm.panel_size_m > 0  # (a passive panel has no LED but shines)
    ]
    sources = [lm.p_true for lm in lms] + [np.asarray(g.p_world, float) for g in world.glints]
    ids = [lm.id for lm in lms] + [-1] * len(world.glints)
    return SiteTruth(
        sources=np.array(sources, dtype=np.float64).reshape(-1, 3),
        source_ids=np.array(ids, dtype=np.int64),
        camera_true=rig.camera_true,
        camera_nominal=rig.camera_nominal,
        surveyed={lm.id: lm.p_surveyed for lm in world.landmarks.values()},
        T_world_body=rig.robot.T_world_body,
    )


def _cache_key(run: Run, duration_s: float) -> str:
    h = hashlib.sha256()
    h.update(run.scenario.read_bytes())
    h.update(repr((run.robot, run.lens, run.calibration, run.seed, duration_s)).encode())
    for f in sorted((ROOT / "sim").glob("*.py")):
        if f.name not in ("cli.py", "chessboard.py"):  # not used to simulate
            h.update(f.read_bytes())
    return h.hexdigest()[:16]


def recording_for(
    run: Run, sc: Scenario, work: Path, duration_s: float, fresh: bool = False
) -> tuple[Path, list[tuple[int, int]]]:
    """The run's simulated recording in the work folder (simulated unless cached) and its
    kidnaps, (picked up, put down) times in ns. Simulated into a folder of its own and then
    renamed, so that two benchmarks sharing the work folder never read a half-written one
    (the one that loses the race waits for the other's)."""
    rec = work / f"{run.name}-{_cache_key(run, duration_s)}"
    meta = rec / "robustness.json"
    if fresh:
        shutil.rmtree(rec, ignore_errors=True)
    if not meta.is_file() and not rec.exists():
        tmp = work / f".{rec.name}.{os.getpid()}.part"
        shutil.rmtree(tmp, ignore_errors=True)
        summary = simulate_recording(sc, tmp, seed=run.seed, duration_s=duration_s, robot=run.robot)
        (tmp / meta.name).write_text(json.dumps({"kidnaps": summary.kidnaps}))
        try:
            tmp.rename(rec)
        except OSError:  # another process got there first
            shutil.rmtree(tmp, ignore_errors=True)
    deadline = time.monotonic() + 3600.0
    while not meta.is_file():  # another process is simulating it
        if time.monotonic() > deadline:
            raise TimeoutError(f"{rec}: no {meta.name} after an hour")
        time.sleep(2.0)
    kidnaps = [(int(a), int(b)) for a, b in json.loads(meta.read_text())["kidnaps"]]
    return rec, kidnaps


def _replay_run(run: Run, sc: Scenario, work: Path, duration_s: float, fresh: bool) -> Score:
    rec, kidnaps = recording_for(run, sc, work, duration_s, fresh)
    poses = rec.parent / f".{rec.name}.{os.getpid()}.poses.csv"  # this process's own
    with poses.open("w", encoding="utf-8", newline="\n") as f:
        replay(rec, f, threads=1)
    results = [_row(line) for line in poses.read_text().splitlines()[1:]]
    poses.unlink()
    t_gt, gt = read_groundtruth(rec)
    index = {int(t): k for k, t in enumerate(t_gt.tolist())}
    unwrapped = np.unwrap(gt[:, 2])

    def truth(t_ns: int) -> tuple[float, float, float]:
        k = index.get(t_ns)
        if k is not None:
            return float(gt[k, 0]), float(gt[k, 1]), float(gt[k, 2])
        x, y = (float(np.interp(t_ns, t_gt, gt[:, j])) for j in (0, 1))
        return x, y, float(np.interp(t_ns, t_gt, unwrapped))

    _, world, rig, _ = recording_site(sc, seed=run.seed, robot=run.robot)
    t0 = int(t_gt[0]) if len(t_gt) else 0
    return score(results, truth, site_truth(world, rig), kidnaps=kidnaps, t_start_ns=t0)


def _row(line: str) -> FrameResult:
    """One row of poses.csv (see `recording.replay_cli`)."""
    t, x, y, th, mode, _, _, _, ids = line.split(",")[:9]
    pose = (float(x), float(y), float(th)) if x else None
    return FrameResult(int(t), pose, mode, tuple(int(i) for i in ids.split()))


def _live_run(run: Run, sc: Scenario, duration_s: float) -> Score:
    from bench.robustness_live import run_live

    live = run_live(sc, robot=run.robot, seed=run.seed, duration_s=duration_s)
    results = [r for r in live.results if r.t_ns in live.truth]
    rig = live.site.rig(run.robot or sc.robots[0].name)
    return score(
        results,
        live.truth.__getitem__,
        site_truth(live.site.world, rig),
        kidnaps=live.kidnaps,
        t_start_ns=live.t_start_ns,
    )


def execute(job: tuple[Run, Path, bool, bool]) -> dict[str, Any]:
    """Simulate, localize and score one run (a worker process's job)."""
    run, work, quick, fresh = job
    duration = min(run.duration_s, QUICK_S) if quick else run.duration_s
    t0 = time.perf_counter()
    sc = run.build()
    s = (
        _live_run(run, sc, duration)
        if run.loop == "leds"
        else _replay_run(run, sc, work, duration, fresh)
    )
    out = dataclasses.asdict(s)
    out.update(
        name=run.name,
        covers=run.covers,
        loop=run.loop,
        held_out=run.held_out,
        duration_s=duration,
        wall_s=time.perf_counter() - t0,
        failed=check_targets(s, run.targets),
        has_targets=bool(run.targets),
    )
    return out


def check_targets(s: Score, targets: dict[str, float]) -> list[str]:
    """The targets a score misses, described ("p95 3.1 cm > 2")."""
    missed = []
    if "p95_cm" in targets and not 100 * s.p95_m <= targets["p95_cm"]:
        missed.append(f"p95 {100 * s.p95_m:.1f} cm > {targets['p95_cm']:g}")
    h = math.degrees(s.heading_mean_rad)
    if "heading_mean_deg" in targets and not h <= targets["heading_mean_deg"]:
        missed.append(f"heading mean {h:.3f} deg > {targets['heading_mean_deg']:g}")
    if "landmark_min" in targets and s.share("landmark") < targets["landmark_min"]:
        missed.append(
            f"landmark {100 * s.share('landmark'):.0f} % < {100 * targets['landmark_min']:g}"
        )
    if "misidentified" in targets and s.misidentified > targets["misidentified"]:
        missed.append(f"misidentified {s.misidentified} > {targets['misidentified']:g}")
    if "recover_s" in targets:
        worst = [r if r is not None else math.inf for r in s.recover_s]
        if worst and max(worst) > targets["recover_s"]:
            missed.append(f"recovery {max(worst):.1f} s > {targets['recover_s']:g}")
    return missed


def _pct(row: dict[str, Any], mode: str) -> str:
    return f"{100 * row['modes'].get(mode, 0) / max(row['frames'], 1):.0f}"


COLUMNS = (
    "run",
    "loop",
    "frames",
    "p95 cm",
    "max cm",
    "hdg mean deg",
    "hdg max deg",
    "landmark %",
    "DR %",
    "lost %",
    "other %",
    "wrong ID",
    "gross",
    "DR > 25 cm",
    "recover s",
    "targets",
)


def table(rows: list[dict[str, Any]]) -> str:
    """The matrix as one markdown table."""
    lines = ["| " + " | ".join(COLUMNS) + " |", "|" + "---|" * len(COLUMNS)]
    for r in rows:
        n = max(r["frames"], 1)
        known = sum(r["modes"].get(m, 0) for m in ("landmark", "dead_reckoning", "lost"))
        rec = " ".join("never" if v is None else f"{v:.1f}" for v in r["recover_s"]) or "-"
        verdict = "; ".join(r["failed"]) if r["failed"] else ("met" if r["has_targets"] else "-")
        cells = [
            f"{r['name']} (held out)" if r["held_out"] else r["name"],
            r["loop"],
            str(r["frames"]),
            f"{100 * r['p95_m']:.1f}",
            f"{100 * r['max_m']:.1f}",
            f"{math.degrees(r['heading_mean_rad']):.3f}",
            f"{math.degrees(r['heading_max_rad']):.2f}",
            _pct(r, "landmark"),
            _pct(r, "dead_reckoning"),
            _pct(r, "lost"),
            f"{100 * (r['frames'] - known) / n:.0f}",
            str(r["wrong_id"]),
            str(r["gross"]),
            str(r["dr_off"]),
            rec,
            verdict,
        ]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def comparison(rows: list[dict[str, Any]], baseline: list[dict[str, Any]]) -> str:
    """A markdown table of the headline figures against a baseline run's JSON: "now (was)"."""
    before = {r["name"]: r for r in baseline}
    head = ("run", "p95 cm", "hdg mean deg", "landmark %", "lost %", "misidentified", "recover s")
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]

    def figures(r: dict[str, Any]) -> list[str]:
        rec = " ".join("never" if v is None else f"{v:.1f}" for v in r["recover_s"]) or "-"
        return [
            f"{100 * r['p95_m']:.1f}",
            f"{math.degrees(r['heading_mean_rad']):.3f}",
            _pct(r, "landmark"),
            _pct(r, "lost"),
            str(r["misidentified"]),
            rec,
        ]

    for r in rows:
        was = before.get(r["name"])
        now = figures(r)
        cells = (
            now if was is None else [f"{a} ({b})" for a, b in zip(now, figures(was), strict=True)]
        )
        lines.append("| " + " | ".join([r["name"], *cells]) + " |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--only",
        action="append",
        default=[],
        metavar="PATTERN",
        help="runs whose name matches this glob (repeatable)",
    )
    parser.add_argument("--quick", action="store_true", help=f"at most {QUICK_S:g} s per run")
    parser.add_argument("--jobs", type=int, default=2, help="worker processes (default 2)")
    parser.add_argument(
        "--held-out",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="include the held-out runs (default yes)",
    )
    parser.add_argument("--json", type=Path, default=None, help="write the figures here")
    parser.add_argument(
        "--baseline",
        type=Path,
        default=None,
        metavar="JSON",
        help="also print the headline figures against this earlier --json (e.g. "
        "bench/robustness/results/before.json)",
    )
    parser.add_argument(
        "--work",
        type=Path,
        default=Path(tempfile.gettempdir()) / "irloc-robustness",
        help="recordings are cached here",
    )
    parser.add_argument("--fresh", action="store_true", help="simulate again, ignoring the cache")
    args = parser.parse_args(argv)
    runs = load_matrix(MATRIX_FILES[0], held_out=False)
    if args.held_out:
        runs += load_matrix(MATRIX_FILES[1], held_out=True)
    if args.only:
        runs = [r for r in runs if any(fnmatch.fnmatch(r.name, p) for p in args.only)]
    if not runs:
        print("no run matches", file=sys.stderr)
        return 1
    args.work.mkdir(parents=True, exist_ok=True)
    jobs = [(r, args.work, args.quick, args.fresh) for r in runs]
    t0 = time.perf_counter()
    if args.jobs > 1 and len(jobs) > 1:
        with multiprocessing.get_context("spawn").Pool(min(args.jobs, len(jobs))) as pool:
            rows = []
            for row in pool.imap(execute, jobs):
                rows.append(row)
                print(
                    f"  {row['name']}: done in {row['wall_s']:.0f} s", file=sys.stderr, flush=True
                )
    else:
        rows = [execute(j) for j in jobs]
    print(table(rows))
    print()
    for r in rows:
        for note in r["notes"]:
            print(f"- {r['name']}: {note}")
    if args.baseline is not None:
        print("\nNow (baseline):\n")
        print(comparison(rows, json.loads(args.baseline.read_text())))
    print(f"\n{len(rows)} runs in {time.perf_counter() - t0:.0f} s (wall)")
    if args.json is not None:
        args.json.write_text(json.dumps(rows, indent=1, default=str))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
