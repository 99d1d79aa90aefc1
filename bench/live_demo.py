"""The live demo through its REST API: start `irloc serve` (fresh data directory, no viewer)
with some settings, poll it for a while and print per robot the first fix, the lost events,
the share of each mode and the age of its latest pose.

    .venv/bin/python bench/live_demo.py NAME SECONDS PORT [IRLOC_SETTING=VALUE ...]
    .venv/bin/python bench/live_demo.py sched 180 8101 IRLOC_LED_POLICY=scheduled

`GET /robots` every 0.5 s gives the modes (first fix: the first poll in landmark mode,
identification at the start included in the shares), `GET /robots/{name}/pose` the pose's
`age_s`, `GET /events` the `robot_lost` events. Runs started side by side share the
machine's load; only those compare (docs/design/2026-12-02-led-schedule-default.md).
"""

from __future__ import annotations

import collections
import json
import os
import subprocess
import sys
import tempfile
import time
import urllib.request
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]


def main(argv: list[str]) -> int:
    if len(argv) < 3:
        print(__doc__)
        return 2
    name, seconds, port = argv[0], float(argv[1]), int(argv[2])
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    for kv in argv[3:]:
        key, _, value = kv.partition("=")
        env[key] = value
    data = tempfile.mkdtemp(prefix=f"live_{name}_")
    cmd = [
        sys.executable,
        "-m",
        "irloc",
        "serve",
        "--no-viewer",
        "--port",
        str(port),
        "--data-dir",
        data,
    ]
    proc = subprocess.Popen(
        cmd, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, env=env, text=True, cwd=ROOT
    )
    assert proc.stdout is not None
    key = None
    while key is None:
        line = proc.stdout.readline()
        if not line:
            print(f"{name}: the server stopped before printing its key", file=sys.stderr)
            return 1
        if "first admin API key" in line:
            key = line.rsplit(": ", 1)[1].strip()

    def get(path: str) -> Any:
        req = urllib.request.Request(
            f"http://127.0.0.1:{port}/api/v1{path}", headers={"Authorization": f"Bearer {key}"}
        )
        with urllib.request.urlopen(req, timeout=10) as r:
            return json.loads(r.read())

    while True:
        try:
            get("/robots")
            break
        except OSError:
            time.sleep(0.2)
    t0 = time.time()
    first: dict[str, float] = {}
    modes: dict[str, collections.Counter[str]] = collections.defaultdict(collections.Counter)
    ages: dict[str, list[float]] = collections.defaultdict(list)
    loads: list[float] = []
    try:
        while (t := time.time() - t0) < seconds:
            for robot in get("/robots"):
                n, mode = robot["name"], robot["mode"]
                modes[n][mode] += 1
                if mode == "landmark":
                    first.setdefault(n, t)
                age = get(f"/robots/{n}/pose").get("age_s")
                if age is not None:
                    ages[n].append(float(age))
            loads.append(os.getloadavg()[0])
            time.sleep(0.5)
        events = get("/events?limit=500")
    finally:
        proc.terminate()
        proc.wait(timeout=30)
    lost = collections.Counter(e["robot"] for e in events if e["kind"] == "robot_lost")
    print(f"== {name} ({seconds:.0f} s, load {min(loads):.1f}-{max(loads):.1f})")
    for n in sorted(modes):
        total = sum(modes[n].values())
        shares = ", ".join(f"{m} {100 * c / total:.1f} %" for m, c in modes[n].most_common())
        a = sorted(ages[n]) or [float("nan")]
        print(
            f"  {n}: first fix {first.get(n, float('nan')):.1f} s, lost {lost.get(n, 0)}; "
            f"{shares}; pose age median {a[len(a) // 2]:.3f} s, "
            f"p95 {a[min(int(0.95 * len(a)), len(a) - 1)]:.3f} s, max {a[-1]:.3f} s"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
