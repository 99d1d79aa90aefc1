"""Run the localizer over a recording, one result per listed frame (`irloc replay`,
`irloc export`, `irloc report`).

Odometry, LED changes and decoded frames go to `localizer.Localizer` in time order (its LED
requests are ignored: the LED states come from `leds.csv`). PNGs are decoded ahead on a
thread pool (decoding releases the GIL, so it runs on the other cores while the localizer
works on this one); the GIL's switch interval is shortened meanwhile so that a finished
decode is not kept waiting (restored afterwards).
"""

from __future__ import annotations

import os
import sys
import time
from collections import deque
from collections.abc import Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import numpy.typing as npt

from localizer.config import LocalizerConfig
from localizer.events import FrameObserved, NoPose, PoseEstimate
from localizer.localizer import Localizer
from recording.reader import FrameEntry, Recording, iter_timeline

ImageU8 = npt.NDArray[np.uint8]

_SWITCH_INTERVAL_S = 0.0005  # GIL hand-over while replaying (CPython's default: 0.005)


@dataclass(frozen=True, eq=False)
class Localized:
    """The localizer's answer to one listed frame.

    Attributes:
        entry: the frame's line of cam0/data.csv.
        estimate: the pose (or no pose) at the frame's time.
        image: the decoded frame, None when missing or unreadable (then the estimate is the
            odometry's, from `Localizer.skip_frame`).
        cpu_s: CPU time of this thread in the localizer for this frame (the odometry and
            LED events since the previous frame included), seconds.
    """

    entry: FrameEntry
    estimate: PoseEstimate | NoPose
    image: ImageU8 | None
    cpu_s: float


def decode_threads() -> int:
    """Threads that decode PNGs ahead of the localizer: one per core this process may use."""
    cores = os.sched_getaffinity(0) if hasattr(os, "sched_getaffinity") else None
    return max(1, len(cores) if cores else (os.cpu_count() or 1))


def decode_frame(path: Path) -> ImageU8 | None:
    """The frame as 8-bit grayscale, or None when missing or unreadable."""
    if not path.is_file():
        return None
    image = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
    return None if image is None else np.asarray(image, dtype=np.uint8)


def localize(
    rec: Recording,
    *,
    config: LocalizerConfig | None = None,
    threads: int | None = None,
) -> Iterator[Localized]:
    """Localize every listed frame of `rec`, in file order.

    Args:
        rec: the recording (`recording.reader.read_recording`).
        config: localizer tuning.
        threads: PNG decoding threads (default `decode_threads()`).
    """
    loc = Localizer(rec.camera, rec.landmark_map, rec.robot, config)
    workers = threads or decode_threads()
    depth = 2 * workers + 2  # frames decoded ahead
    switch = sys.getswitchinterval()
    sys.setswitchinterval(min(switch, _SWITCH_INTERVAL_S))
    try:
        with ThreadPoolExecutor(max_workers=workers, thread_name_prefix="png") as pool:
            yield from _run(rec, loc, pool, depth)
    finally:
        sys.setswitchinterval(switch)


def _run(
    rec: Recording, loc: Localizer, pool: ThreadPoolExecutor, depth: int
) -> Iterator[Localized]:
    """The loop: frames decoded `depth` ahead on `pool`, in order."""
    ahead: deque[Future[ImageU8 | None]] = deque()
    queued = iter(rec.frames)
    cpu_ns = 0
    for item in iter_timeline(rec):
        if not isinstance(item, FrameEntry):
            t0 = time.thread_time_ns()
            loc.handle(item)
            cpu_ns += time.thread_time_ns() - t0
            continue
        while len(ahead) < depth:
            nxt = next(queued, None)
            if nxt is None:
                break
            ahead.append(pool.submit(decode_frame, nxt.path))
        image = ahead.popleft().result()
        t0 = time.thread_time_ns()
        if image is None:
            est: PoseEstimate | NoPose = loc.skip_frame(item.t_ns)
        else:
            outs = loc.handle(FrameObserved(item.t_ns, image))
            est = next(o for o in outs if isinstance(o, PoseEstimate | NoPose))
        cpu_ns += time.thread_time_ns() - t0
        yield Localized(item, est, image, cpu_ns * 1e-9)
        cpu_ns = 0
