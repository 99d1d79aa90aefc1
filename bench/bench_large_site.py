"""A 20,000-landmark site: map import, restart and `/healthz` times.

The app runs in this process (FastAPI's TestClient: the same lifespan as `irloc serve`) on a
SQLite file in a temporary folder, with the live site (the `demo` scenario's robots and the
simulated radio) running on the imported map.

1. import: `PUT /api/v1/map` of N landmarks (a 0.75 m grid at 2.5 m, each with a radio) on a
   running site, request to response;
2. restart: stop the app, start it again on the same folder, until `/healthz` answers;
3. `/healthz`: median and max of 50 requests on the running site with the map.

Targets (issue 18): import <= 3 s, restart <= 5 s, `/healthz` <= 10 ms.

Usage: .venv/bin/python bench/bench_large_site.py [--landmarks 20000] [--profile FILE]
"""

from __future__ import annotations

import argparse
import cProfile
import statistics
import tempfile
import time
import warnings
from contextlib import nullcontext
from pathlib import Path
from typing import Any

with warnings.catch_warnings():
    warnings.simplefilter("ignore")
    from fastapi.testclient import TestClient

from live.settings import Settings
from server.main import create_app

TARGETS = {"import_s": 3.0, "restart_s": 5.0, "healthz_ms": 10.0}


def grid_map(n: int, spacing_m: float = 0.75) -> dict[str, Any]:
    """map.json of `n` landmarks on a square grid, each with its own radio address."""
    side = int(n**0.5) + 1
    return {
        "landmarks": [
            {
                "id": i + 1,
                "x": (i % side) * spacing_m,
                "y": (i // side) * spacing_m,
                "z": 2.5,
                "radio": f"0013A200{i + 1:08X}",
            }
            for i in range(n)
        ]
    }


def _app(data_dir: Path) -> Any:
    settings = Settings(data_dir=data_dir, viewer_enabled=False, battery_interval_s=None)
    return create_app(settings)


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--landmarks", type=int, default=20_000)
    p.add_argument("--profile", type=Path, help="write a cProfile of the three steps here")
    args = p.parse_args()
    doc = grid_map(args.landmarks)
    profiler = cProfile.Profile() if args.profile else None
    results: dict[str, float] = {}
    with tempfile.TemporaryDirectory() as tmp, profiler or nullcontext():
        data_dir = Path(tmp)
        app = _app(data_dir)
        with TestClient(app) as client:
            key = app.state.services.initial_admin_key
            t0 = time.perf_counter()
            r = client.put("/api/v1/map", json=doc, headers={"Authorization": f"Bearer {key}"})
            results["import_s"] = time.perf_counter() - t0
            assert r.status_code == 200 and r.json() == {"landmarks": args.landmarks}, r.text
        t0 = time.perf_counter()
        app = _app(data_dir)
        with TestClient(app) as client:
            r = client.get("/healthz")
            results["restart_s"] = time.perf_counter() - t0
            assert r.json()["landmarks"] == args.landmarks, r.text
            times = []
            for _ in range(50):
                t1 = time.perf_counter()
                assert client.get("/healthz").status_code == 200
                times.append((time.perf_counter() - t1) * 1e3)
            results["healthz_ms"] = statistics.median(times)
            results["healthz_max_ms"] = max(times)
    if profiler is not None:
        profiler.dump_stats(args.profile)
    print(f"{args.landmarks} landmarks (demo site's robots, simulated radio):")
    for name, value in results.items():
        target = TARGETS.get(name)
        verdict = "" if target is None else (" ok" if value <= target else " OVER")
        limit = "" if target is None else f" (target <= {target:g})"
        print(f"  {name:15s} {value:9.3f}{limit}{verdict}")
    return 0 if all(results[k] <= v for k, v in TARGETS.items()) else 1


if __name__ == "__main__":
    raise SystemExit(main())
