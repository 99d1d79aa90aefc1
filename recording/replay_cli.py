"""`irloc replay REC --out poses.csv`: run the localizer over a recording.

Reads the recording (docs/recording.md), feeds odometry, LED changes and
decoded frames to `localizer.Localizer` in time order (its LED requests are ignored: the LED
states come from `leds.csv`) and writes one row per listed frame:

    timestamp_ns,x,y,theta,mode,cov_xx,cov_yy,cov_tt,landmarks

`x,y,theta` and the covariances are empty while there is no pose; `landmarks` lists the IDs
used in that frame, space-separated. A missing or unreadable frame is skipped with a warning
and counted (its row holds the odometry pose). A malformed file ends the run with one line
naming the file and line and exit status 1.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from collections import deque
from collections.abc import Callable, Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path
from typing import TextIO

import cv2
import numpy as np
import numpy.typing as npt

from localizer.config import LocalizerConfig
from localizer.events import FrameObserved, NoPose, PoseEstimate
from localizer.localizer import Localizer
from recording.reader import (
    FrameEntry,
    Recording,
    RecordingError,
    iter_timeline,
    read_recording,
)

ImageU8 = npt.NDArray[np.uint8]
HEADER = "timestamp_ns,x,y,theta,mode,cov_xx,cov_yy,cov_tt,landmarks"
PROG = "irloc replay"


_SWITCH_INTERVAL_S = 0.0005  # GIL hand-over while replaying (CPython's default: 0.005)


def decode_threads() -> int:
    """Threads that decode PNGs ahead of the localizer: one per core this process may use."""
    cores = os.sched_getaffinity(0) if hasattr(os, "sched_getaffinity") else None
    return max(1, len(cores) if cores else (os.cpu_count() or 1))


def _decode(path: Path) -> ImageU8 | None:
    """The frame as 8-bit grayscale, or None when missing or unreadable."""
    if not path.is_file():
        return None
    image = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
    return None if image is None else np.asarray(image, dtype=np.uint8)


def format_row(est: PoseEstimate | NoPose) -> str:
    """One CSV row of the output."""
    if isinstance(est, NoPose):
        return f"{est.t_ns},,,,{est.mode},,,,"
    c = est.covariance
    ids = " ".join(str(i) for i in est.landmark_ids)
    return (
        f"{est.t_ns},{est.x:.6f},{est.y:.6f},{est.theta:.7f},{est.mode},"
        f"{c[0, 0]:.3e},{c[1, 1]:.3e},{c[2, 2]:.3e},{ids}"
    )


def replay(
    root: Path,
    out: TextIO,
    *,
    config: LocalizerConfig | None = None,
    warn: Callable[[str], None] = lambda _: None,
    progress: Callable[[int], Iterator[None]] | None = None,
    threads: int | None = None,
) -> tuple[int, int]:
    """Localize a recording, writing rows to `out`.

    Args:
        root: the recording folder.
        out: where the CSV goes (the header is written first).
        config: localizer tuning.
        warn: called with a message for each skipped frame.
        progress: optional callback given the frame count, returning an iterator advanced
            once per frame (a progress bar).
        threads: PNG decoding threads (default `decode_threads()`). Decoding releases the
            GIL, so it runs on the other cores while the localizer works on this one; the
            GIL's switch interval is shortened meanwhile so that a finished decode is not
            kept waiting (restored afterwards).

    Returns:
        (frames written, frames skipped).

    Raises:
        RecordingError: a malformed file, naming the file and line.
    """
    rec = read_recording(root)
    loc = Localizer(rec.camera, rec.landmark_map, rec.robot, config)
    ticks = progress(len(rec.frames)) if progress is not None else None
    out.write(HEADER + "\n")
    workers = threads or decode_threads()
    depth = 2 * workers + 2  # frames decoded ahead
    switch = sys.getswitchinterval()
    sys.setswitchinterval(min(switch, _SWITCH_INTERVAL_S))
    try:
        with ThreadPoolExecutor(max_workers=workers, thread_name_prefix="png") as pool:
            written, skipped = _run(rec, loc, pool, depth, out, warn, ticks)
    finally:
        sys.setswitchinterval(switch)
    return written, skipped


def _run(
    rec: Recording,
    loc: Localizer,
    pool: ThreadPoolExecutor,
    depth: int,
    out: TextIO,
    warn: Callable[[str], None],
    ticks: Iterator[None] | None,
) -> tuple[int, int]:
    """The replay loop: frames decoded `depth` ahead on `pool`, in order."""
    written = skipped = 0
    ahead: deque[Future[ImageU8 | None]] = deque()
    queued = iter(rec.frames)
    for item in iter_timeline(rec):
        if not isinstance(item, FrameEntry):
            loc.handle(item)
            continue
        while len(ahead) < depth:
            nxt = next(queued, None)
            if nxt is None:
                break
            ahead.append(pool.submit(_decode, nxt.path))
        image = ahead.popleft().result()
        if image is None:
            skipped += 1
            warn(f"{item.path}: missing or unreadable frame (cam0/data.csv:{item.line}), skipped")
            est: PoseEstimate | NoPose = loc.skip_frame(item.t_ns)
        else:
            outs = loc.handle(FrameObserved(item.t_ns, image))
            est = next(o for o in outs if isinstance(o, PoseEstimate | NoPose))
        out.write(format_row(est) + "\n")
        written += 1
        if ticks is not None:
            next(ticks, None)
    return written, skipped


def _bar(total: int) -> Iterator[None]:
    from tqdm import tqdm

    with tqdm(total=total, unit="frame", desc="replay", file=sys.stderr) as bar:
        while True:
            bar.update(1)
            yield None


def main(argv: list[str] | None = None) -> int:
    """Entry point of `irloc replay`; returns the exit status."""
    parser = argparse.ArgumentParser(prog=PROG, description=__doc__.splitlines()[0])
    parser.add_argument("recording", type=Path, help="the recording folder")
    parser.add_argument("--out", type=Path, required=True, help="poses.csv to write")
    parser.add_argument("--quiet", action="store_true", help="no progress bar or warnings")
    args = parser.parse_args(argv)
    show = not args.quiet and sys.stderr.isatty()

    def warn(msg: str) -> None:
        if args.quiet:
            return
        if show:
            from tqdm import tqdm

            tqdm.write(f"{PROG}: warning: {msg}", file=sys.stderr)
        else:
            print(f"{PROG}: warning: {msg}", file=sys.stderr)

    start = time.perf_counter()
    tmp = args.out.with_name(args.out.name + ".part")
    try:
        with tmp.open("w", encoding="utf-8", newline="\n") as f:
            written, skipped = replay(args.recording, f, warn=warn, progress=_bar if show else None)
        tmp.replace(args.out)
    except RecordingError as exc:
        tmp.unlink(missing_ok=True)
        print(f"{PROG}: {exc}", file=sys.stderr)
        return 1
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        print(f"{PROG}: {exc.filename or args.out}: {exc.strerror or exc}", file=sys.stderr)
        return 1
    if not args.quiet:
        took = time.perf_counter() - start
        note = f", {skipped} unreadable frames skipped" if skipped else ""
        print(
            f"{PROG}: {written} poses written to {args.out} in {took:.1f} s{note}", file=sys.stderr
        )
    return 0
