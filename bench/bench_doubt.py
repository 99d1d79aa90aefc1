"""Doubted landmarks on the live demo site: false doubts on a correct map, then how soon a
landmark moved in the map is doubted.

Runs the API app with the `demo` virtual site in-process (real localizers, gateway and
simulated radio), reads the doubted landmarks (`services.commissioning`, as `GET
/api/v1/commissioning/doubts` and the viewer do) every
0.5 s for `--seconds` from the start, prints each landmark that becomes doubted with the
simulator's true LED brightness (0: its LED died: a true doubt), then moves the landmark
nearest robot r2's whole patrol `--move-m` metres in the map and prints how long it took to
be doubted. Wall-clock figures on a shared machine: repeat them.

    .venv/bin/python -m bench.bench_doubt [--seed 5] [--seconds 180] [--move-m 0.25]

(as a module from the repository root: it reuses the test suite's live-site helpers).
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from live.commissioning_service import Commissioning
from store.models import LandmarkUpdate
from tests.web.conftest import landmark_always_in_view, running_site


def doubted(site: Commissioning) -> dict[int, str]:
    return {lid: d.reason for lid, d in site.doubted().items()}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=5)
    ap.add_argument("--seconds", type=float, default=180.0, help="correct map watched, s")
    ap.add_argument("--move-m", type=float, default=0.25, help="then move a landmark (0: no)")
    ap.add_argument("--timeout", type=float, default=90.0, help="wait for its doubt, s")
    args = ap.parse_args()
    with running_site(Path(tempfile.mkdtemp()), seed=args.seed) as (app, _port):
        services = app.state.services
        site = services.commissioning
        start = time.monotonic()
        first: dict[int, float] = {}
        while time.monotonic() - start < args.seconds:
            time.sleep(0.5)
            for lid, why in doubted(site).items():
                if lid not in first:
                    first[lid] = time.monotonic() - start
                    bright = services.virtual_site.world.landmarks[lid].battery.led_brightness()
                    print(
                        f"t={first[lid]:5.1f} s landmark {lid} doubted: {why} "
                        f"(true LED brightness {bright:.2f})"
                    )
        print(f"seed {args.seed}: {args.seconds:.0f} s, {len(first)} landmarks doubted")
        if args.move_m <= 0:
            return
        lid = landmark_always_in_view(services, "r2")
        lm = services.map.get(lid)
        services.map.update(lid, LandmarkUpdate(y=lm.y + args.move_m), actor="bench")
        moved = time.monotonic()
        while time.monotonic() - moved < args.timeout:
            time.sleep(0.5)
            if lid in doubted(site):
                print(
                    f"landmark {lid} moved {args.move_m} m in the map: doubted after "
                    f"{time.monotonic() - moved:.1f} s"
                )
                return
        print(
            f"landmark {lid} moved {args.move_m} m: not doubted in {args.timeout} s "
            f"({site.doubt(lid)})"
        )


if __name__ == "__main__":
    main()
