"""How long `irloc export` and `irloc report` take on a simulated recording, and how big the
MCAP files are against the recording's PNGs.

`irloc simulate paper_testbed` (30 s by default), then per profile the export's wall clock
and CPU time (the process's, all threads: PNG decoding ahead, the localizer, spot
detection, serialization), per frame and against `irloc replay` on the same recording, and
the file size against the sum of the frames' PNGs (the images are stored as recorded, so the
rest is the overhead of everything else); then the report's time.

    .venv/bin/python bench/bench_export.py [--duration 30] [--recording REC]
"""

from __future__ import annotations

import argparse
import io
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from export.cli import export_recording  # noqa: E402
from export.report import write_report  # noqa: E402
from irloc.simulate_cli import main as simulate_main  # noqa: E402
from recording.reader import read_recording  # noqa: E402
from recording.replay_cli import replay  # noqa: E402


def _timed(fn: Callable[[], object]) -> tuple[float, float]:
    """(wall seconds, CPU seconds of the process)."""
    w0, c0 = time.perf_counter(), time.process_time()
    fn()
    return time.perf_counter() - w0, time.process_time() - c0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=30.0, help="simulated seconds")
    parser.add_argument("--recording", type=Path, default=None, help="reuse a recording")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        rec = args.recording or Path(tmp) / "paper_testbed"
        if args.recording is None:
            sim = ["paper_testbed", str(rec), "--quiet", "--duration", str(args.duration)]
            if simulate_main(sim) != 0:
                return 1
        frames = read_recording(rec).frames
        png = sum(f.path.stat().st_size for f in frames)
        n = len(frames)
        wall, cpu = _timed(lambda: replay(rec, io.StringIO()))
        print(f"{n} frames, PNGs {png / 1e6:.1f} MB")
        print(f"  {'':<16}{'wall s':>8}{'CPU s':>8}{'CPU ms/frame':>14}{'file MB':>9}{'/ PNGs':>8}")
        print(f"  {'irloc replay':<16}{wall:>8.2f}{cpu:>8.2f}{1000 * cpu / n:>14.2f}")
        for profile in ("foxglove", "ros2"):
            out = Path(tmp) / f"{profile}.mcap"
            wall, cpu = _timed(lambda p=profile, o=out: export_recording(rec, o, p))  # type: ignore[misc]
            size = out.stat().st_size
            print(
                f"  {'export ' + profile:<16}{wall:>8.2f}{cpu:>8.2f}{1000 * cpu / n:>14.2f}"
                f"{size / 1e6:>9.1f}{size / png:>8.3f}"
            )
        html = Path(tmp) / "report.html"
        wall, cpu = _timed(lambda: write_report(rec, html))
        print(
            f"  {'report':<16}{wall:>8.2f}{cpu:>8.2f}{1000 * cpu / n:>14.2f}"
            f"{html.stat().st_size / 1e6:>9.2f}"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
