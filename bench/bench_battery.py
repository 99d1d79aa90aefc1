"""Landmark battery life: `all_lit` against the LED schedule, with awake and sleeping radios.

    .venv/bin/python bench/bench_battery.py [--shift-s 240] [--idle-s 60] [--sleep-period 0.5]
        [--sites demo floor50] [--seed 0]

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
that day's duty (`sim.energy.predict_life_days`: the discharge curve integrated, the LED
current falling with the voltage, the radio's mean current in its mode, each command's
charge). The demo's store-room landmark on tiny cells is left out of the battery figures.

Per robot: time to the first fix from a cold start (server restart: gateway start-up sweep
and identification), the median over `--cold-runs` separate cold starts of up to `--cold-s`
each (seeds `--seed`, `--seed` + 1, ...; nan: none within it; the first fix has a long tail
in every configuration, so one run says little); over the shift
(from `--warmup-s`, or 10 s after the robot's first fix when that came later) the share of
frames in landmark mode and the p95 position error against the truth. Commands/s: the
gateway's radio commands in the shift window.
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

from bench.virtual_site import SiteRun, parked, robot_stats, run_site, run_virtual  # noqa: E402
from server.settings import Settings  # noqa: E402
from sim.energy import (  # noqa: E402
    DutyCycle,
    LandmarkEnergy,
    RadioSleep,
    combine_duty,
    predict_life_days,
)
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
            "led": e.led_mah / t_h, "idle": e.idle_mah / t_h, "wake": e.wake_mah / t_h,
            "message": e.message_mah / t_h, "awake": e.awake_s / max(e.time_s, 1e-9),
            "tx": e.tx_s / max(e.time_s, 1e-9),
        }  # fmt: skip
    return out


def day_breakdown(shift: SiteRun, idle: SiteRun, lids: list[int]) -> dict[str, float]:
    """The day's mean current by term (8 h shift + 16 h idle), over `lids`, mA (and the
    median landmark's awake and transmit shares)."""
    b_s, b_i = breakdown(shift), breakdown(idle)
    day = {
        k: float(np.mean([(SHIFT_H * b_s[i][k] + IDLE_H * b_i[i][k]) / 24 for i in lids]))
        for k in (*TERMS, "awake", "tx")
    }
    return day


def measure(site: str, config: str, args: argparse.Namespace) -> Row:
    policy = "all_lit" if config == "all_lit" else "scheduled"
    sleep_s = args.sleep_period if config.endswith("sleep") else None
    settings = Settings(
        data_dir=Path(tempfile.mkdtemp()), led_policy=policy, radio_sleep_period_s=sleep_s
    )
    t0 = time.perf_counter()
    shift = run_virtual(
        run_site(site, settings, args.warmup_s + args.shift_s, seed=args.seed,
                 measure_from_s=args.warmup_s, known_poses=True)
    )  # fmt: skip
    colds = [
        run_virtual(run_site(site, settings, args.cold_s, seed=args.seed + k, until_fixed=True))
        for k in range(args.cold_runs)
    ]
    idle_sc = parked(load_scenario(site), args.idle_s + 10.0)
    idle = run_virtual(
        run_site(idle_sc, settings, args.idle_s, seed=args.seed, known_poses=True,
                 measure_from_s=args.idle_s - args.idle_measure_s)
    )  # fmt: skip
    wall = time.perf_counter() - t0
    d_shift, d_idle = duties(shift), duties(idle)
    sleep = None if sleep_s is None else RadioSleep(sleep_s)
    counted = [
        lid for lid in shift.landmark_ids if shift.capacity_mah.get(lid, 0.0) >= STANDARD_MAH
    ]
    life = {
        lid: predict_life_days(
            combine_duty([(SHIFT_H, d_shift[lid]), (IDLE_H, d_idle[lid])]), sleep=sleep
        )
        for lid in counted
    }
    lives = list(life.values())
    worst_id = min(life, key=life.__getitem__)
    n = len(shift.landmark_ids)
    robots = {name: robot_stats(shift, name) for name in sorted(shift.poses)}
    for name, stats in robots.items():  # the first fix of a cold start (server restart)
        fixes = [robot_stats(cold, name)["first_fix_s"] for cold in colds]
        fixes = [f if math.isfinite(f) else math.inf for f in fixes]  # none within --cold-s
        stats["first_fix_s"] = float(np.median(fixes))
        stats["first_fix_max_s"] = max(fixes)
    return Row(
        site, config,
        float(np.median(lives)), float(np.min(lives)),
        float(np.mean(shift.lit_samples)) / n, float(np.mean(idle.lit_samples)) / n,
        shift.commands / shift.seconds, robots, wall, args.warmup_s,
        day_breakdown(shift, idle, counted), day_breakdown(shift, idle, [worst_id]), worst_id,
    )  # fmt: skip


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
    print("\n| site | config | landmarks | LED | asleep/idle | wake-ups | commands | total "
          "| awake % | tx % |")  # fmt: skip
    print("|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        for label, m in (("mean", r.mean_ma), (f"worst ({r.worst_id})", r.worst_ma)):
            total = sum(m[k] for k in TERMS)
            print(
                f"| {r.site} | {r.config} | {label} | {m['led']:.2f} | {m['idle']:.3f} "
                f"| {m['wake']:.3f} | {m['message']:.3f} | {total:.2f} "
                f"| {100 * m['awake']:.2f} | {100 * m['tx']:.3f} |"
            )


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
    return ok  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sites", nargs="+", default=["demo", "floor50"])
    parser.add_argument("--configs", nargs="+",
                        default=["all_lit", "scheduled", "scheduled+sleep"])  # fmt: skip
    parser.add_argument("--shift-s", type=float, default=240.0, help="shift window, s")
    parser.add_argument("--warmup-s", type=float, default=15.0, help="not counted, s")
    parser.add_argument("--cold-s", type=float, default=60.0,
                        help="longest cold start run for the first fix, s")  # fmt: skip
    parser.add_argument("--cold-runs", type=int, default=5,
                        help="cold starts (seeds) whose median first fix is reported")  # fmt: skip
    parser.add_argument("--idle-s", type=float, default=60.0, help="idle window, s")
    parser.add_argument("--idle-measure-s", type=float, default=30.0,
                        help="idle duty counted over the end of the idle window, s")  # fmt: skip
    parser.add_argument("--sleep-period", type=float, default=0.5, help="XBee SP, s")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    if args.warmup_s < 0 or args.shift_s <= 0 or not 0 < args.idle_measure_s <= args.idle_s:
        parser.error("need warmup >= 0, shift > 0 and 0 < idle-measure <= idle")
    rows = []
    for site in args.sites:
        for config in args.configs:
            row = measure(site, config, args)
            rows.append(row)
            print(f"{site} {config}: median {row.median_days:.1f} d, worst "
                  f"{row.worst_days:.1f} d, lit {100 * row.lit_fraction:.1f} %, "
                  f"{row.wall_s:.0f} s wall", flush=True)  # fmt: skip
    print_rows(rows)
    check_targets(rows)
    print(
        f"\nday = {SHIFT_H:.0f} h shift at the shift window's duty + {IDLE_H:.0f} h idle at "
        f"the idle window's; shift {args.shift_s:.0f} s (from {args.warmup_s:.0f} s), idle "
        f"{args.idle_s:.0f} s (last {args.idle_measure_s:.0f} s), SP {args.sleep_period} s"
    )
    return 0 if all(math.isfinite(r.median_days) for r in rows) else 1


if __name__ == "__main__":
    raise SystemExit(main())
