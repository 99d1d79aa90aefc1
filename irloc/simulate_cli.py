"""`irloc simulate SCENARIO OUTDIR`: write a recording of a simulated scenario."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from irloc.simulated_recording import simulate_recording
from sim.cameras import CALIBRATION_LEVELS, LENSES
from sim.scenario import SCENARIOS, load_scenario


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="irloc simulate",
        description=(
            "Simulate one robot of a scenario and write a recording (the format irloc replay "
            "reads) plus groundtruth.csv, starting with the identification sweep."
        ),
    )
    parser.add_argument(
        "scenario", help=f"built-in scenario ({', '.join(SCENARIOS)}) or a scenario YAML file"
    )
    parser.add_argument("outdir", type=Path, help="recording folder to write")
    parser.add_argument("--seed", type=int, default=None, help="override the scenario's seed")
    parser.add_argument(
        "--duration", type=float, default=None, metavar="S", help="seconds to simulate"
    )
    parser.add_argument("--lens", choices=LENSES, default=None, help="override the lens model")
    parser.add_argument(
        "--calibration",
        choices=tuple(CALIBRATION_LEVELS),
        default=None,
        help="override every camera's calibration error (the lens handed over vs the true one)",
    )
    parser.add_argument("--robot", default=None, help="which robot (default: the first)")
    parser.add_argument("--force", action="store_true", help="write into a non-empty OUTDIR")
    parser.add_argument("--quiet", action="store_true", help="no progress or summary")
    return parser


def main(argv: list[str]) -> int:
    args = build_parser().parse_args(argv)
    if args.duration is not None and not args.duration > 0:
        print("irloc simulate: --duration must be positive", file=sys.stderr)
        return 2
    out: Path = args.outdir
    if out.exists() and (not out.is_dir() or any(out.iterdir())) and not args.force:
        print(f"irloc simulate: {out} exists and is not empty (use --force)", file=sys.stderr)
        return 2
    try:
        scenario = load_scenario(args.scenario)
        if args.calibration is not None:
            scenario = scenario.with_calibration(CALIBRATION_LEVELS[args.calibration])
    except ValueError as exc:
        print(f"irloc simulate: {exc}", file=sys.stderr)
        return 2
    duration = scenario.duration_s if args.duration is None else args.duration
    bar = None
    if not args.quiet and sys.stderr.isatty():
        from tqdm import tqdm

        bar = tqdm(total=round(duration, 1), unit="s", desc=scenario.name, file=sys.stderr)

    def progress(done_s: float) -> None:
        if bar is not None:
            bar.update(round(done_s, 1) - bar.n)

    try:
        summary = simulate_recording(
            scenario,
            out,
            seed=args.seed,
            duration_s=duration,
            lens=args.lens,
            robot=args.robot,
            progress=progress,
        )
    except ValueError as exc:
        print(f"irloc simulate: {exc}", file=sys.stderr)
        return 2
    finally:
        if bar is not None:
            bar.close()
    if not args.quiet:
        print(
            f"wrote {out}: {summary.frames} frames, {summary.odometry} odometry samples, "
            f"{summary.led_changes} LED changes (identification sweep until "
            f"{summary.sweep_end_ns / 1e9:.2f} s), groundtruth.csv"
        )
    return 0
