"""The pose history's read path for playback: a week of one robot at one pose a second
(604,800 rows, `live.zones_history`'s rate) in a SQLite file, read as the viewer and
`/history/poses?max_points=` read it (thinned in the database) and as `/history/coverage`
counts it (grouped in the database), against reading every row.

    .venv/bin/python bench/bench_history.py [--days 7] [--robots 1] [--max-points 3000]

Prints each read's time and rows; the ratios are from one run (the machine is shared).
"""

from __future__ import annotations

import argparse
import tempfile
import time
from datetime import UTC, datetime, timedelta
from pathlib import Path

import numpy as np
from sqlalchemy import insert

from store.db import make_engine, migrate
from store.models import PoseRecord
from store.zones import PoseHistory


def fill(history: PoseHistory, robots: int, days: float) -> int:
    """Kept poses every second over `days` for each robot (a random walk); how many."""
    n = int(days * 86_400)
    t0 = datetime.now(UTC) - timedelta(days=days)
    rng = np.random.default_rng(1)
    with history.engine.begin() as conn:
        for r in range(robots):
            xy = np.cumsum(rng.normal(0.0, 0.3, size=(n, 2)), axis=0) % 40.0
            for a in range(0, n, 50_000):
                rows = [
                    {
                        "robot": f"r{r + 1}",
                        "t": t0 + timedelta(seconds=k),
                        "t_ns": k * 10**9,
                        "x": float(xy[k, 0]),
                        "y": float(xy[k, 1]),
                        "theta": 0.0,
                        "sigma_m": 0.01,
                        "mode": "landmark",
                    }
                    for k in range(a, min(n, a + 50_000))
                ]
                conn.execute(insert(PoseRecord), rows)
    return n * robots


def timed(fn):  # type: ignore[no-untyped-def]
    t = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - t


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--days", type=float, default=7.0)
    ap.add_argument("--robots", type=int, default=1)
    ap.add_argument("--max-points", type=int, default=3000)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        engine = make_engine(f"sqlite:///{Path(tmp) / 'irloc.db'}")
        migrate(engine)
        history = PoseHistory(engine)
        n, fill_s = timed(lambda: fill(history, args.robots, args.days))
        print(
            f"{n} kept poses ({args.robots} robot(s), {args.days:g} days) stored in {fill_s:.1f} s"
        )
        (thin, total), thin_s = timed(
            lambda: history.thinned(robot="r1", max_points=args.max_points)
        )
        print(f"thinned to {len(thin)} of {total} poses of r1: {thin_s:.2f} s")
        (cells, counted), cell_s = timed(lambda: history.cell_counts(0.5))
        print(f"heatmap: {counted} poses in {len(cells)} cells of 0.5 m: {cell_s:.2f} s")
        every, all_s = timed(lambda: history.query(robot="r1", limit=10**7))
        print(
            f"every pose of r1 read whole: {len(every)} rows, {all_s:.2f} s "
            f"(thinned: {all_s / max(thin_s, 1e-9):.1f}x faster, "
            f"{len(every) / max(len(thin), 1):.0f}x fewer points to the browser)"
        )
        engine.dispose()


if __name__ == "__main__":
    main()
