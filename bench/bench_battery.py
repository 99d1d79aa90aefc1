"""Landmark battery life: `all_lit` against the LED schedule, with awake and sleeping radios.

    .venv/bin/python bench/bench_battery.py [--shift-s 240] [--idle-s 60] [--sleep-period 0.5]
        [--sites demo floor50] [--configs all_lit scheduled scheduled+sleep] [--seeds 0 ...]
        [--cold-runs 5]
    .venv/bin/python bench/bench_battery.py --cold-only [--sites floor50]
        [--configs all_lit scheduled+sleep] [--cold-runs 5]

For each site (`demo`: three robots patrolling without a break; `floor50`: 50 landmarks,
three robots) and each configuration (`all_lit` with awake radios, `scheduled` with awake
radios, `scheduled` with radios in cyclic sleep), the live site runs on virtual time
(`bench/virtual_site.py`: the server's gateway, LED coordinator, scheduler and localizers,
the simulated radio with its latencies and sleep cycles, spot-level cameras), faster than
real time.

What is measured (virtual time, per landmark): in a shift window of `--shift-s` (robots
patrolling; after `--warmup-s` from a start with each robot's pose known to 2 cm, as when a
shift starts on a running server) the share of time its LED is lit and the radio commands
it receives; in an idle window of `--idle-s` (every robot parked at its start; counted over
the last `--idle-measure-s`) the same (the idle window starts with each robot's pose known
to 2 cm, as at the end of a shift, not from a cold start). What is extrapolated: the day =
8 h of shift + 16 h idle at those duty cycles (the patrols repeat their loops, so a window
of a few loops stands for the shift), and the battery life of a fresh pair of AA cells at
that day's duty (`lighting.energy.predict_life_days`: the discharge curve integrated, the LED
current falling with the voltage, the radio's mean current in its mode, each command's
charge). The demo's store-room landmark on tiny cells is left out of the battery figures.

Per robot: time to the first fix from a cold start (server restart: gateway start-up sweep
and identification), the median over `--cold-runs` separate cold starts of up to `--cold-s`
each (seeds the first of `--seeds`, +1, ...; nan: none within it, or `--cold-runs 0`; the
first fix has a long tail in every configuration, so one run says little); over the shift
(from `--warmup-s`, or 10 s after the robot's first fix when that came later) the share of
frames in landmark mode and the p95 position error against the truth, pooled over the
shift windows of every seed in `--seeds` (each seed draws its own survey error, camera
calibration error and odometry bias; the battery figures average their duty), each seed's
p95 printed as well. Commands/s: the gateway's radio commands in the shift window.

`--cold-only` runs only the cold starts, for the configurations asked for, and prints per
robot each start's first fix, the median and the worst, and the largest position error
of any pose before the run stops (a wrong first fix shows there).
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from bench.virtual_site import (  # noqa: E402
    SiteRun,
    parked,
    robot_stats,
    run_site,
    run_virtual,
    steady_frames,
)
from lighting.energy import (  # noqa: E402
    DutyCycle,
    LandmarkEnergy,
    RadioSleep,
    combine_duty,
    predict_life_days,
)
from live.settings import Settings  # noqa: E402
from sim.scenario import load_scenario  # noqa: E402

SHIFT_H, IDLE_H = 8.0, 16.0
STANDARD_MAH = 2000.0
"""Landmarks starting with less charge than this (the demo's store room) are left out."""


@dataclass(frozen=True)
class Row:
    site: str
    config: str
    median_days: float
    worst_days: float
    lit_fraction: float
    idle_lit_fraction: float
    commands_per_s: float
    robots: dict[str, dict[str, float]]
    wall_s: float
    warmup_s: float
    mean_ma: dict[str, float]
    worst_ma: dict[str, float]
    worst_id: int


def duties(run: SiteRun) -> dict[int, DutyCycle]:
    """Per landmark: measured LED duty, commands per second and the radio's mean current
    (what its radio did: asleep, waking, receiving and answering, awake after commands)."""
    out = {}
    for lid in run.landmark_ids:
        e = run.energy.get(lid, LandmarkEnergy())
        out[lid] = DutyCycle(e.led_on_s / run.seconds, e.messages / run.seconds, e.radio_ma)
    return out


TERMS = ("led", "idle", "wake", "message")


def breakdown(run: SiteRun) -> dict[int, dict[str, float]]:
    """Per landmark: mean current of each term over the run, mA (LED; radio asleep or
    listening idle; cyclic wake-ups; commands and the awake time after them), and the
    radio's awake and transmit shares."""
    out = {}
    for lid in run.landmark_ids:
        e = run.energy.get(lid, LandmarkEnergy())
        t_h = max(e.time_s, 1e-9) / 3600.0
        out[lid] = {
            "led": e.led_mah / t_h,
            "idle": e.idle_mah / t_h,
            "wake": e.wake_mah / t_h,
            "message": e.message_mah / t_h,
            "awake": e.awake_s / max(e.time_s, 1e-9),
            "tx": e.tx_s / max(e.time_s, 1e-9),
        }
    return out


def day_breakdown(shift: SiteRun, idle: SiteRun, lids: list[int]) -> dict[str, float]:
    """The day's mean current by term (8 h shift + 16 h idle), over `lids`, mA (and the
    median landmark's awake and transmit shares); `shift`: the first seed's window."""
    b_s, b_i = breakdown(shift), breakdown(idle)
    day = {
        k: float(np.mean([(SHIFT_H * b_s[i][k] + IDLE_H * b_i[i][k]) / 24 for i in lids]))
        for k in (*TERMS, "awake", "tx")
    }
    return day


def pooled_stats(shifts: list[SiteRun], name: str) -> dict[str, float]:
    """A robot's steady state over the shift windows of every seed: the landmark-mode
    share of all their frames and the p95 of all their errors (the pool), plus each seed's
    own p95 (`p95_cm_<seed index>`) and the latest start of a steady state (s)."""
    modes: list[str] = []
    errors: list[float] = []
    out: dict[str, float] = {}
    from_s = 0.0
    for k, run in enumerate(shifts):
        m, e, _, f = steady_frames(run, name)
        modes += m
        errors += e
        out[f"p95_cm_{k}"] = float(np.percentile(e, 95)) if e else math.nan
        from_s = max(from_s, f) if math.isfinite(f) else math.inf
    out["landmark"] = sum(x == "landmark" for x in modes) / max(len(modes), 1)
    out["p95_cm"] = float(np.percentile(errors, 95)) if errors else math.nan
    out["from_s"] = from_s
    return out


def measure(site: str, config: str, args: argparse.Namespace) -> Row:
    sleep_s = args.sleep_period if config.endswith("sleep") else None
    settings = _settings(config, args)
    t0 = time.perf_counter()
    seed0 = args.seeds[0]
    shifts = [
        run_virtual(
            run_site(
                site,
                settings,
                args.warmup_s + args.shift_s,
                seed=seed,
                measure_from_s=args.warmup_s,
                known_poses=True,
            )
        )
        for seed in args.seeds
    ]
    shift = shifts[0]
    colds = [
        run_virtual(run_site(site, settings, args.cold_s, seed=seed0 + k, until_fixed=True))
        for k in range(args.cold_runs)
    ]
    idle_sc = parked(load_scenario(site), args.idle_s + 10.0)
    idle = run_virtual(
        run_site(
            idle_sc,
            settings,
            args.idle_s,
            seed=seed0,
            known_poses=True,
            measure_from_s=args.idle_s - args.idle_measure_s,
        )
    )
    wall = time.perf_counter() - t0
    d_shifts, d_idle = [duties(s) for s in shifts], duties(idle)
    sleep = None if sleep_s is None else RadioSleep(sleep_s)
    counted = [
        lid for lid in shift.landmark_ids if shift.capacity_mah.get(lid, 0.0) >= STANDARD_MAH
    ]
    life = {
        lid: predict_life_days(
            combine_duty(
                [(SHIFT_H / len(d_shifts), d[lid]) for d in d_shifts] + [(IDLE_H, d_idle[lid])]
            ),
            sleep=sleep,
        )
        for lid in counted
    }
    lives = list(life.values())
    worst_id = min(life, key=life.__getitem__)
    n = len(shift.landmark_ids)
    robots = {name: pooled_stats(shifts, name) for name in sorted(shift.poses)}
    for name, stats in robots.items():  # the first fix of a cold start (server restart)
        fixes = [robot_stats(cold, name)["first_fix_s"] for cold in colds]
        fixes = [f if math.isfinite(f) else math.inf for f in fixes]  # none within --cold-s
        stats["first_fix_s"] = float(np.median(fixes)) if fixes else math.nan
        stats["first_fix_max_s"] = max(fixes, default=math.nan)
    return Row(
        site,
        config,
        float(np.median(lives)),
        float(np.min(lives)),
        float(np.mean([np.mean(s.lit_samples) for s in shifts])) / n,
        float(np.mean(idle.lit_samples)) / n,
        sum(s.commands for s in shifts) / sum(s.seconds for s in shifts),
        robots,
        wall,
        args.warmup_s,
        day_breakdown(shift, idle, counted),
        day_breakdown(shift, idle, [worst_id]),
        worst_id,
    )


def cold_starts(site: str, config: str, args: argparse.Namespace) -> dict[str, list[float]]:
    """Only the cold starts: per robot, each start's first fix (s); printed with the
    largest position error of its poses before the run stopped (cm)."""
    out: dict[str, list[float]] = {}
    worst_cm: dict[str, float] = {}
    for k in range(args.cold_runs):
        cold = run_virtual(
            run_site(
                site, _settings(config, args), args.cold_s, seed=args.seeds[0] + k, until_fixed=True
            )
        )
        for name in sorted(cold.poses):
            fix = robot_stats(cold, name)["first_fix_s"]
            out.setdefault(name, []).append(fix if math.isfinite(fix) else math.inf)
            err = [
                100 * math.hypot(u.x - tr[0], u.y - tr[1])
                for u, tr in cold.poses[name]
                if u.x is not None and u.y is not None and tr is not None
            ]
            worst_cm[name] = max([worst_cm.get(name, 0.0), *err])
        line = ", ".join(f"{n} {v[-1]:.2f}" for n, v in out.items())
        print(f"  {site} {config} seed {args.seeds[0] + k}: first fix s: {line}", flush=True)
    for name, fixes in out.items():
        print(
            f"{site} {config} {name}: median {np.median(fixes):.2f} s, worst "
            f"{max(fixes):.2f} s, error up to {worst_cm[name]:.1f} cm"
        )
    return out


def _settings(config: str, args: argparse.Namespace) -> Settings:
    sleep_s = args.sleep_period if config.endswith("sleep") else None
    return Settings(
        data_dir=Path(tempfile.mkdtemp()),
        led_policy="all_lit" if config == "all_lit" else "scheduled",
        radio_sleep_period_s=sleep_s,
    )


def print_rows(rows: list[Row]) -> None:
    print(
        "\n| site | config | median days | worst days | lit % (shift) | lit % (idle) "
        "| commands/s | robot: landmark % / p95 cm / first fix s (median, max) | wall s |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        robots = "; ".join(
            f"{n}: {100 * s['landmark']:.1f} / {s['p95_cm']:.2f} / {s['first_fix_s']:.1f} "
            f"({s['first_fix_max_s']:.1f})"
            + ("" if s["from_s"] <= r.warmup_s else f" (from {s['from_s']:.0f} s)")
            for n, s in r.robots.items()
        )
        print(
            f"| {r.site} | {r.config} | {r.median_days:.1f} | {r.worst_days:.1f} "
            f"| {100 * r.lit_fraction:.1f} | {100 * r.idle_lit_fraction:.1f} "
            f"| {r.commands_per_s:.2f} | {robots} | {r.wall_s:.0f} |"
        )
    print(
        "\nwhere the charge goes, the day's mean current in mA (8 h shift + 16 h idle; "
        "mean landmark, and the worst one): LED | radio asleep / listening | cyclic wake-ups "
        "| commands + awake after them | total (radio awake %, transmitting %)"
    )
    print(
        "\n| site | config | landmarks | LED | asleep/idle | wake-ups | commands | total "
        "| awake % | tx % |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        for label, m in (("mean", r.mean_ma), (f"worst ({r.worst_id})", r.worst_ma)):
            total = sum(m[k] for k in TERMS)
            print(
                f"| {r.site} | {r.config} | {label} | {m['led']:.2f} | {m['idle']:.3f} "
                f"| {m['wake']:.3f} | {m['message']:.3f} | {total:.2f} "
                f"| {100 * m['awake']:.2f} | {100 * m['tx']:.3f} |"
            )


def print_seeds(rows: list[Row], seeds: list[int]) -> None:
    """Each robot's p95 error per seed's shift window and pooled, and the ratio to the
    same site's `all_lit` (per seed and pooled)."""
    by = {(r.site, r.config): r for r in rows}
    print("\np95 error per seed (cm; ratio to all_lit on the same seed):")
    print("| site | config | robot | " + " | ".join(f"seed {s}" for s in seeds) + " | pooled |")
    print("|---|---|---|" + "---|" * (len(seeds) + 1))
    for r in rows:
        base = by.get((r.site, "all_lit"))
        for name, st in r.robots.items():
            cells = []
            for key in [f"p95_cm_{k}" for k in range(len(seeds))] + ["p95_cm"]:
                cell = f"{st[key]:.3f}"
                if base is not None and r is not base:
                    cell += f" ({st[key] / base.robots[name][key]:.2f}x)"
                cells.append(cell)
            print(f"| {r.site} | {r.config} | {name} | " + " | ".join(cells) + " |")


def check_targets(rows: list[Row]) -> bool:
    """The issue's targets; prints each with its verdict."""
    by = {(r.site, r.config): r for r in rows}
    ok = True

    def verdict(name: str, passed: bool, detail: str) -> None:
        nonlocal ok
        ok &= passed
        print(f"  {'meets ' if passed else 'MISSES'} {name}: {detail}")

    print("\ntargets:")
    base, best = by.get(("floor50", "all_lit")), by.get(("floor50", "scheduled+sleep"))
    if base is not None and best is not None:
        verdict(
            "median life >= 20x all_lit awake",
            best.median_days >= 20 * base.median_days,
            f"{best.median_days:.1f} d vs {base.median_days:.2f} d "
            f"({best.median_days / base.median_days:.1f}x)",
        )
        verdict(
            "worst life >= 5x all_lit awake",
            best.worst_days >= 5 * base.worst_days,
            f"{best.worst_days:.1f} d vs {base.worst_days:.2f} d "
            f"({best.worst_days / base.worst_days:.1f}x)",
        )
        for name, b in base.robots.items():
            s = best.robots[name]
            verdict(
                f"{name} landmark mode within 1 point",
                s["landmark"] >= b["landmark"] - 0.01,
                f"{100 * s['landmark']:.1f} % vs {100 * b['landmark']:.1f} %",
            )
            verdict(
                f"{name} p95 <= 1.25x",
                s["p95_cm"] <= 1.25 * b["p95_cm"],
                f"{s['p95_cm']:.2f} cm vs {b['p95_cm']:.2f} cm",
            )
            verdict(
                f"{name} first fix <= 2x",
                s["first_fix_s"] <= 2 * b["first_fix_s"],
                f"{s['first_fix_s']:.1f} s vs {b['first_fix_s']:.1f} s",
            )
    for config in ("scheduled", "scheduled+sleep"):
        demo = by.get(("demo", config))
        if demo is not None:
            verdict(
                f"demo {config} lit <= 35 %",
                demo.lit_fraction <= 0.35,
                f"{100 * demo.lit_fraction:.1f} %",
            )
    return ok


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sites", nargs="+", default=["demo", "floor50"])
    parser.add_argument("--configs", nargs="+", default=["all_lit", "scheduled", "scheduled+sleep"])
    parser.add_argument("--shift-s", type=float, default=240.0, help="shift window, s")
    parser.add_argument("--warmup-s", type=float, default=15.0, help="not counted, s")
    parser.add_argument(
        "--cold-s", type=float, default=60.0, help="longest cold start run for the first fix, s"
    )
    parser.add_argument(
        "--cold-runs",
        type=int,
        default=5,
        help="cold starts (seeds) whose median first fix is reported",
    )
    parser.add_argument("--idle-s", type=float, default=60.0, help="idle window, s")
    parser.add_argument(
        "--idle-measure-s",
        type=float,
        default=30.0,
        help="idle duty counted over the end of the idle window, s",
    )
    parser.add_argument("--sleep-period", type=float, default=0.5, help="XBee SP, s")
    parser.add_argument(
        "--seeds",
        type=int,
        nargs="+",
        default=[0],
        help="a shift window per seed (the robots' figures pooled over them); "
        "the idle window and the first cold start take the first",
    )
    parser.add_argument(
        "--cold-only", action="store_true", help="only the cold starts' first fixes, per robot"
    )
    args = parser.parse_args(argv)
    if args.cold_only:
        for site in args.sites:
            for config in args.configs:
                cold_starts(site, config, args)
        return 0
    if args.warmup_s < 0 or args.shift_s <= 0 or not 0 < args.idle_measure_s <= args.idle_s:
        parser.error("need warmup >= 0, shift > 0 and 0 < idle-measure <= idle")
    rows = []
    for site in args.sites:
        for config in args.configs:
            row = measure(site, config, args)
            rows.append(row)
            print(
                f"{site} {config}: median {row.median_days:.1f} d, worst "
                f"{row.worst_days:.1f} d, lit {100 * row.lit_fraction:.1f} %, "
                f"{row.wall_s:.0f} s wall",
                flush=True,
            )
    print_rows(rows)
    if len(args.seeds) > 1:
        print_seeds(rows, args.seeds)
    check_targets(rows)
    print(
        f"\nday = {SHIFT_H:.0f} h shift at the shift window's duty + {IDLE_H:.0f} h idle at "
        f"the idle window's; shift {args.shift_s:.0f} s (from {args.warmup_s:.0f} s), idle "
        f"{args.idle_s:.0f} s (last {args.idle_measure_s:.0f} s), SP {args.sleep_period} s"
    )
    return 0 if all(math.isfinite(r.median_days) for r in rows) else 1


if __name__ == "__main__":
    raise SystemExit(main())
