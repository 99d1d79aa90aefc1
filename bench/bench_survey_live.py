"""Live survey benchmark: the running estimate's update time and memory against drive length,
and its accuracy against the truth (docs/survey.md, "The live estimate").

A drive of up to 15 minutes is simulated at the level of spot centres (true projection +
0.15 px noise, as `bench/bench_survey.py`) on a site of `sim.lit_site` (24 landmarks on
7.2 m x 4.8 m, neighbours 70 cm apart and more, ceiling 2.5 m +-5 cm, the usual odometry and
calibration errors, two anchors surveyed to 1 mm lit one at a time at the start, then every
LED lit; every other landmark taped, x and y off by 12 cm). The live survey's running
estimate (`survey.incremental.update`) is updated every `--every` seconds of drive, each
update given the frames since its window began, as `live/survey/live.py` hands them over.

Printed at 1, 5 and 15 minutes: the update time (CPU and wall: median and largest of the last
minute's updates, each given 4 s of new drive; before that minute the bench updates every
30 s of drive to get there sooner, `--between`), the state's size (the prior and the carried
trajectory, bytes) and the peak memory the updates allocated (`tracemalloc`), the estimate's
accuracy (landmarks placed, x-y p95 / max, z max, the share within 2 sigma), and, for the
ratio, one whole-drive solve of the drive so far (what the live survey did before: it
solved the whole drive again at each update).

    .venv/bin/python bench/bench_survey_live.py [--minutes 1,5,15] [--seed 29] [--every 4]
"""

from __future__ import annotations

import argparse
import contextlib
import time
import tracemalloc

import numpy as np

from bench.bench_survey import score, truncated
from sim.lit_site import anchor_pair, anchor_sweep_then_lit, lit_site_scenario, taped_map
from sim.survey_floor import simulate_survey_spots
from survey.bundle import BundleConfig, solve_survey
from survey.drive import survey_problem
from survey.incremental import IncrementalConfig, IncrementalSurvey, update, window_of
from survey.incremental_file import to_arrays

NS = 1_000_000_000


def state_bytes(state: IncrementalSurvey) -> int:
    return sum(int(a.nbytes) for a in to_arrays(state).values())


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--minutes", default="1,5,15", help="report at these drive times, minutes")
    p.add_argument("--seed", type=int, default=29)
    p.add_argument("--every", type=float, default=4.0, help="drive seconds between updates")
    p.add_argument(
        "--between",
        type=float,
        default=30.0,
        help="drive seconds between updates outside the minute before each mark (the bench's "
        "shortcut: the state is the same kind, the timed updates are the last minute's)",
    )
    p.add_argument("--lag", type=float, default=IncrementalConfig().lag_s)
    p.add_argument("--no-batch", action="store_true", help="skip the whole-drive solves")
    args = p.parse_args(argv)
    marks = sorted(float(m) for m in args.minutes.split(","))
    scenario = lit_site_scenario(seed=args.seed)
    anchors = anchor_pair(scenario)
    end_s = marks[-1] * 60.0
    t0 = time.perf_counter()
    drive = simulate_survey_spots(
        scenario, end_s, lambda t: anchor_sweep_then_lit(anchors), seed=args.seed
    )
    landmarks = taped_map(drive.map_records, anchors, np.random.default_rng(args.seed))
    truth = drive.landmarks_true
    print(
        f"seed {args.seed}: {len(truth)} landmarks, anchors {anchors}; simulated "
        f"{end_s / 60:.0f} min ({len(drive.frame_t_ns)} frames) in "
        f"{time.perf_counter() - t0:.0f} s; an update every {args.every:.0f} s of drive, "
        f"lag {args.lag:.0f} s"
    )
    full = truncated(drive, end_s, landmarks)
    cfg = BundleConfig(max_iterations=12, window_iterations=4)  # the live survey's
    inc = IncrementalConfig(lag_s=args.lag)
    state = IncrementalSurvey()
    times: list[tuple[float, float, float]] = []  # (drive s, update wall s, update CPU s)
    print(
        "\n| drive min | updates | update CPU s median (last min) | update CPU s max (last min) "
        "| update wall s median | state kB | peak alloc MB | placed | x-y p95 mm | x-y max mm "
        "| z max mm | x-y / z in 2 sigma | whole-drive solve CPU s (wall s) |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    t_drive = args.every
    first_t = int(full.frame_t_ns[0])
    tracemalloc.start()
    for mark in marks:
        tracemalloc.reset_peak()
        while t_drive <= mark * 60.0 + 1e-9:
            now = truncated(drive, t_drive, landmarks)
            window = window_of(now, state.window_start_ns)
            began, cpu = time.perf_counter(), time.process_time()
            with contextlib.suppress(ValueError):  # an anchor not seen yet: tried again next
                state = update(state, window, anchors, cfg, inc)
            times.append((t_drive, time.perf_counter() - began, time.process_time() - cpu))
            timed = t_drive > mark * 60.0 - 60.0 or state.result is None
            if timed:
                t_drive += args.every
            else:
                t_drive = min(t_drive + args.between, mark * 60.0 - 60.0 + args.every)
        _, peak = tracemalloc.get_traced_memory()
        recent = [c for s, _, c in times if s > mark * 60.0 - 60.0]
        recent_wall = [w for s, w, _ in times if s > mark * 60.0 - 60.0]
        batch = "-"
        if not args.no_batch:
            tracemalloc.stop()
            b0, c0 = time.perf_counter(), time.process_time()
            sd = truncated(drive, mark * 60.0, landmarks)
            solve_survey(survey_problem(sd, anchors), cfg)
            batch = f"{time.process_time() - c0:.1f} ({time.perf_counter() - b0:.0f})"
            tracemalloc.start()
        r = state.result
        if r is None:
            print(f"| {mark:.0f} | {len(times)} | no estimate yet |")
            continue
        s = score(r, truth)
        n = s["n"]
        print(
            f"| {mark:.0f} | {state.updates} | {np.median(recent):.2f} | {max(recent):.2f} "
            f"| {np.median(recent_wall):.1f} | {state_bytes(state) / 1e3:.0f} "
            f"| {peak / 1e6:.0f} | {n:.0f}/{len(truth) - 2} | {1000 * s['xy_p95']:.1f} "
            f"| {1000 * s['xy_max']:.1f} | {1000 * s['z_max']:.1f} "
            f"| {100 * s['inside_xy'] / n:.0f} % / {100 * s['inside_z'] / n:.0f} % | {batch} |",
            flush=True,
        )
    del first_t
    print(f"\nupdates in all: {len(times)}, CPU {sum(c for _, _, c in times):.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
