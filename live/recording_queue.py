"""`QueuedRecording`: a live recording written from its own thread, never the frame path's.

The robot's feeding thread only queues (a bounded queue of `RecordingLimits.queue_items`;
a frame that finds it full is dropped and counted in `frames_dropped`, an odometry sample
in `samples_dropped`). The writer thread
writes through a `recording.writer.RecordingWriter` and stops the recording, and only it,
with a reason handed to `on_stop`, when:

- a write fails (a full disk: `OSError` ENOSPC; any other error),
- the recording passes `max_bytes` or `max_s`,
- the disk's free space falls under `min_free_bytes`.

A late sample (odometry, LED state or pose older than the last one written: two sources
whose clocks disagree a little) is dropped and counted in `late_dropped`; it does not stop
the recording.
"""

from __future__ import annotations

import errno
import logging
import os
import queue
import shutil
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt

from localizer.events import LedsChanged, NoPose, PoseEstimate
from recording import layout
from recording.writer import RecordingWriter

log = logging.getLogger(__name__)
MIB = 1024 * 1024
CHECK_EVERY_S = 1.0


@dataclass(frozen=True)
class RecordingLimits:
    """Attributes:
    max_bytes: a recording stops when its files pass this size.
    max_s: ... when it has run this long, seconds.
    min_free_bytes: ... when the disk has less free space than this (and does not start).
    queue_items: frames and samples waiting to be written before frames are dropped.
    """

    max_bytes: int = 4096 * MIB
    max_s: float = 3600.0
    min_free_bytes: int = 256 * MIB
    queue_items: int = 64


def free_bytes(path: Path) -> int:
    """Free space of the disk holding `path` (its nearest existing parent)."""
    p = path
    while not p.exists() and p != p.parent:
        p = p.parent
    return shutil.disk_usage(p).free


def check_free_space(root: Path, limits: RecordingLimits) -> None:
    """Raises OSError(ENOSPC) when a recording under `root` must not start."""
    free = free_bytes(root)
    if free < limits.min_free_bytes:
        raise OSError(
            errno.ENOSPC,
            f"recording not started: {free // MIB} MB free on the disk of {root}; recordings "
            f"need {limits.min_free_bytes // MIB} MB free (setting recording_min_free_mb)",
        )


def _size(root: Path) -> int:
    total = 0
    for folder in (root, root / layout.FRAMES_DIR):
        if not folder.is_dir():
            continue
        with os.scandir(folder) as it:
            for entry in it:
                if entry.is_file(follow_symlinks=False):
                    total += entry.stat(follow_symlinks=False).st_size
    return total


Item = tuple[str, Callable[[RecordingWriter], object]]
"""What to write: ("frame" or "sample", the write)."""


class QueuedRecording:
    """See the module. `on_stop(reason)` is called on the writer thread when the recording
    stops by itself (not when `close` is called)."""

    def __init__(
        self,
        writer: RecordingWriter,
        limits: RecordingLimits,
        on_stop: Callable[[str], None],
        *,
        name: str = "recording",
    ) -> None:
        self.writer = writer
        self.limits = limits
        self.on_stop = on_stop
        self.frames_dropped = 0
        self.late_dropped = 0
        self.samples_dropped = 0
        self.frames_written = 0
        self.stopped: str | None = None
        self._queue: queue.Queue[Item | None] = queue.Queue(limits.queue_items)
        self._t0 = time.monotonic()
        self._next_check = self._t0
        self._closed = threading.Event()
        self._thread = threading.Thread(target=self._run, name=f"recorder-{name}", daemon=True)
        self._thread.start()

    @property
    def root(self) -> Path:
        return self.writer.root

    # -- the feeding thread: queue only -----------------------------------------------------
    def _put(self, item: Item) -> bool:
        if self.stopped is not None or self._closed.is_set():
            return False
        try:
            self._queue.put_nowait(item)
        except queue.Full:
            return False
        return True

    def add_frame(self, t_ns: int, image: npt.NDArray[np.uint8]) -> None:
        if not self._put(("frame", lambda w: w.add_frame(t_ns, image))) and not self.stopped:
            self.frames_dropped += 1

    def add_odometry(self, t_ns: int, v_left: float, v_right: float) -> None:
        if not self._put(("sample", lambda w: w.add_odometry(t_ns, v_left, v_right))):
            self.samples_dropped += 0 if self.stopped else 1

    def add_leds(self, event: LedsChanged) -> None:
        self._put(("sample", lambda w: w.add_leds(event)))

    def add_pose(self, estimate: PoseEstimate | NoPose) -> None:
        self._put(("sample", lambda w: w.add_pose(estimate)))

    def close(self) -> Path:
        """Write what is queued, close the files; the folder. Never raises (a failure to
        write the last frames is logged)."""
        self._closed.set()
        self._queue.put(None)
        self._thread.join()
        return self.root

    # -- the writer thread -----------------------------------------------------------------
    def _write(self, item: Item) -> None:
        kind, write = item
        if kind == "frame":
            write(self.writer)
            self.frames_written += 1
            return
        try:
            write(self.writer)
        except ValueError:  # a late sample (or an LED of a landmark added since): skip it
            self.late_dropped += 1

    def _limit_passed(self) -> str | None:
        now = time.monotonic()
        if now < self._next_check:
            return None
        self._next_check = now + CHECK_EVERY_S
        lim = self.limits
        if now - self._t0 > lim.max_s:
            return f"it reached its duration limit ({lim.max_s:g} s)"
        free = free_bytes(self.root)
        if free < lim.min_free_bytes:
            return (
                f"the disk is nearly full ({free // MIB} MB free, the limit is "
                f"{lim.min_free_bytes // MIB} MB)"
            )
        size = _size(self.root)
        if size > lim.max_bytes:
            return f"it reached its size limit ({size // MIB} MB of {lim.max_bytes // MIB} MB)"
        return None

    def _stop(self, reason: str) -> None:
        self.stopped = reason
        try:
            self.writer.close()
        except Exception as exc:
            log.warning("recording %s: closing after the stop: %s", self.root, exc)
        try:
            self.on_stop(reason)
        except Exception:
            log.exception("recording %s: the stop callback failed", self.root)

    def _run(self) -> None:
        while True:
            item = self._queue.get()
            if item is None:
                break
            if self.stopped is not None:
                continue
            try:
                self._write(item)
                reason = self._limit_passed()
            except OSError as exc:
                full = exc.errno in (errno.ENOSPC, errno.EDQUOT)
                reason = "the disk is full" if full else f"a write failed: {exc}"
            except Exception as exc:
                reason = f"a write failed: {type(exc).__name__}: {exc}"
            if reason is not None:
                self._stop(reason)
        if self.stopped is None:
            try:
                self.writer.close()
            except Exception as exc:
                log.warning("recording %s: its last frames were not written: %s", self.root, exc)
