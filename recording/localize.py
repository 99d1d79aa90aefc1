"""Run the localizer over a recording, one result per listed frame (`irloc replay`,
`irloc export`, `irloc report`), or read what the robot's localizer gave live (a live
recording's `live_poses.csv`).

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
from typing import Literal

import cv2
import numpy as np

from localizer.config import LocalizerConfig
from localizer.events import FrameObserved, NoPose, PoseEstimate, RelocalizeRequested
from localizer.localizer import Localizer
from localizer.types import ImageU8
from recording.layout import LIVE_POSES_FILE
from recording.poses_file import estimates_from_track
from recording.reader import FrameEntry, Recording, RecordingError, iter_timeline
from recording.scoring import read_poses
from recording.start_pose import StartPose

PoseSource = Literal["replay", "live"]

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
        why_not: while identifying passive lights by geometry, the last decision and its
            reason ("ambiguous: 82 distinct poses ..."); empty otherwise.
    """

    entry: FrameEntry
    estimate: PoseEstimate | NoPose
    image: ImageU8 | None
    cpu_s: float
    why_not: str = ""


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
    start_pose: StartPose | None = None,
) -> Iterator[Localized]:
    """Localize every listed frame of `rec`, in file order.

    Args:
        rec: the recording (`recording.reader.read_recording`).
        config: localizer tuning.
        threads: PNG decoding threads (default `decode_threads()`).
        start_pose: a prior on the start pose, handed to the localizer as
            `RelocalizeRequested(near=..., radius_m=...)` at its time (default: the
            recording's first event); None: none (pass `rec.start_pose` for the recording's).
    """
    loc = Localizer(rec.camera, rec.landmark_map, rec.robot, config)
    if start_pose is not None:
        t0 = start_pose.t_ns if start_pose.t_ns is not None else first_time_ns(rec)
        near = (start_pose.x, start_pose.y, start_pose.theta)
        loc.handle(RelocalizeRequested(t0, near=near, radius_m=start_pose.radius_m))
    workers = threads or decode_threads()
    depth = 2 * workers + 2  # frames decoded ahead
    switch = sys.getswitchinterval()
    sys.setswitchinterval(min(switch, _SWITCH_INTERVAL_S))
    try:
        with ThreadPoolExecutor(max_workers=workers, thread_name_prefix="png") as pool:
            yield from _run(rec, loc, pool, depth)
    finally:
        sys.setswitchinterval(switch)


def first_time_ns(rec: Recording) -> int:
    """The recording's first timestamp (frames, odometry, IMU, LEDs), 0 when it has none."""
    starts = [f.t_ns for f in rec.frames[:1]] + [e.t_ns for e in rec.leds[:1]]
    starts += [int(a[0]) for a in (rec.odom_t_ns, rec.imu_t_ns) if len(a)]
    return min(starts, default=0)


def _decoded(
    frames: list[FrameEntry], pool: ThreadPoolExecutor, depth: int
) -> Iterator[ImageU8 | None]:
    """The listed frames decoded `depth` ahead on `pool`, in order."""
    ahead: deque[Future[ImageU8 | None]] = deque()
    queued = iter(frames)
    while True:
        while len(ahead) < depth:
            nxt = next(queued, None)
            if nxt is None:
                break
            ahead.append(pool.submit(decode_frame, nxt.path))
        if not ahead:
            return
        yield ahead.popleft().result()


def _run(
    rec: Recording, loc: Localizer, pool: ThreadPoolExecutor, depth: int
) -> Iterator[Localized]:
    """The loop: frames decoded `depth` ahead on `pool`, in order."""
    images = _decoded(rec.frames, pool, depth)
    cpu_ns = 0
    for item in iter_timeline(rec):
        if not isinstance(item, FrameEntry):
            t0 = time.thread_time_ns()
            loc.handle(item)
            cpu_ns += time.thread_time_ns() - t0
            continue
        image = next(images)
        t0 = time.thread_time_ns()
        if image is None:
            est: PoseEstimate | NoPose = loc.skip_frame(item.t_ns)
        else:
            outs = loc.handle(FrameObserved(item.t_ns, image))
            est = next(o for o in outs if isinstance(o, PoseEstimate | NoPose))
        cpu_ns += time.thread_time_ns() - t0
        status = loc.passive_status if est.mode in ("identifying", "lost") else None
        why = "" if status is None else f"{status.status}: {status.reason}"
        yield Localized(item, est, image, cpu_ns * 1e-9, why)
        cpu_ns = 0


def has_live_poses(rec: Recording) -> bool:
    """Whether the recording holds the live localizer's poses (a live recording's
    `live_poses.csv`)."""
    return (rec.root / LIVE_POSES_FILE).is_file()


def pose_source(rec: Recording, poses: PoseSource | None) -> PoseSource:
    """`poses` itself, or when None `live` for a recording with live poses, else `replay`."""
    return poses or ("live" if has_live_poses(rec) else "replay")


def live_poses(rec: Recording, *, threads: int | None = None) -> Iterator[Localized]:
    """What the robot's localizer gave live for every listed frame (`live_poses.csv`), the
    frames decoded as `localize` decodes them; a frame without a row there (recorded after
    the localizer's last answer) is `NoPose(lost)`; `cpu_s` is 0 (not recorded).

    Raises:
        RecordingError: a malformed `live_poses.csv` (file and line named).
    """
    path = rec.root / LIVE_POSES_FILE
    try:
        rows = estimates_from_track(read_poses(path), source=str(path))
    except (OSError, ValueError) as exc:
        what = str(exc).removeprefix(f"{path}").lstrip(":")
        raise RecordingError(path, None, what.strip() or type(exc).__name__) from None
    by_time = {e.t_ns: e for e in rows}
    workers = threads or decode_threads()
    with ThreadPoolExecutor(max_workers=workers, thread_name_prefix="png") as pool:
        images = _decoded(rec.frames, pool, 2 * workers + 2)
        for entry, image in zip(rec.frames, images, strict=True):
            est = by_time.get(entry.t_ns) or NoPose(entry.t_ns, "lost")
            yield Localized(entry, est, image, 0.0)


def localized(
    rec: Recording, poses: PoseSource | None = None, *, threads: int | None = None
) -> Iterator[Localized]:
    """The poses of every listed frame from `poses`: `replay` runs the localizer over the
    recording (`localize`), `live` reads what the robot's localizer gave (`live_poses`);
    None: `live` when the recording has them, else `replay`.

    Raises:
        RecordingError: `live` asked of a recording without live poses, or a malformed file.
    """
    source = pose_source(rec, poses)
    if source == "live":
        if not has_live_poses(rec):
            raise RecordingError(
                rec.root / LIVE_POSES_FILE,
                None,
                "missing: only live recordings hold the live poses (use the replay's)",
            )
        return live_poses(rec, threads=threads)
    return localize(rec, threads=threads)
