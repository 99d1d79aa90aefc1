"""A robot's black box: the last seconds of what its localizer was fed (frames, odometry,
LED states) and what it answered (poses), kept in memory and saved as an ordinary recording
(docs/recording.md) when something goes wrong: a loss, a suspected kidnap, the quality
dropping below a threshold, or an operator's click.

A saved black box is `<recordings>/<robot>-<UTC time>-blackbox-<trigger>/` with
`blackbox.json` (robot, trigger, reason, when), `start_pose.yaml` (the pose at the window's
start, a prior for `irloc replay`) and the catalog's `irloc_recording.json` (trigger
`black_box_<trigger>`: it is listed among the robot's recordings, `GET /recordings`);
`irloc replay` and `irloc export` read it as any recording. Saving runs on a thread of its
own (PNG encoding must not hold up the localizer); the black boxes on disk are kept under
`max_bytes`, the oldest removed first.
"""

from __future__ import annotations

import json
import logging
import shutil
import threading
from collections import deque
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any, Literal

import numpy as np
import yaml

from live.led_filter import only_landmarks
from localizer.camera import CameraModel
from localizer.events import (
    Event,
    FrameObserved,
    LedsChanged,
    NoPose,
    OdometryMeasured,
    PoseEstimate,
)
from localizer.robot import RobotGeometry
from recording.writer import RecordingWriter
from store.recording_catalog import write_meta

Trigger = Literal["lost", "kidnap", "quality", "operator"]
TRIGGERS: tuple[Trigger, ...] = ("lost", "kidnap", "quality", "operator")
META_FILE = "blackbox.json"
START_POSE_FILE = "start_pose.yaml"
_NS = 1e-9
log = logging.getLogger(__name__)


@dataclass(frozen=True)
class BlackBoxConfig:
    """What a black box keeps and when it saves (SI units).

    Attributes:
        seconds: how far back the memory reaches, seconds.
        after_s: the seconds after a trigger saved with it (the aftermath), seconds.
        max_frames: a bound on the frames held in memory (a fast camera).
        quality_below: a pose whose quality falls below this (from at least it) triggers.
        min_interval_s: at most one save per robot per this long (site time), seconds.
        max_bytes: the black boxes on disk are kept under this many bytes (oldest first).
    """

    seconds: float = 20.0
    after_s: float = 3.0
    max_frames: int = 1200
    quality_below: float = 0.2
    min_interval_s: float = 60.0
    max_bytes: int = 2_000_000_000

    def __post_init__(self) -> None:
        if not self.seconds > 0 or self.after_s < 0 or self.min_interval_s < 0:
            raise ValueError(
                f"BlackBoxConfig: need seconds > 0, after_s >= 0, min_interval_s >= 0, got "
                f"{self.seconds!r}, {self.after_s!r}, {self.min_interval_s!r}"
            )
        if self.max_frames < 1 or self.max_bytes < 0 or not 0 <= self.quality_below <= 1:
            raise ValueError(
                f"BlackBoxConfig: need max_frames >= 1, max_bytes >= 0, quality_below in [0, 1], "
                f"got {self.max_frames!r}, {self.max_bytes!r}, {self.quality_below!r}"
            )


@dataclass(frozen=True)
class BlackBoxRecording:
    """A saved black box: its folder and `blackbox.json`."""

    path: Path
    robot: str
    trigger: Trigger
    reason: str | None
    t_ns: int
    saved_at: str
    bytes: int


class BlackBox:
    """One robot's black box (thread-safe: fed on the robot's thread, triggered from any).

    Args:
        robot: the robot's name.
        camera, geometry: written into the recording.
        landmark_records: the map's landmarks as `map.json` records (called at each save).
        root: the recordings folder.
        config: what it keeps and when it saves.
    """

    def __init__(
        self,
        robot: str,
        camera: CameraModel,
        geometry: RobotGeometry,
        landmark_records: Callable[[], list[dict[str, Any]]],
        root: Path,
        config: BlackBoxConfig | None = None,
    ) -> None:
        self.robot, self.camera, self.geometry = robot, camera, geometry
        self._records = landmark_records
        self.root = Path(root)
        self.config = config or BlackBoxConfig()
        self._lock = threading.Lock()
        self._events: deque[Event] = deque()
        self._poses: deque[PoseEstimate | NoPose] = deque()
        self._frames = 0
        self._leds_before: LedsChanged | None = None  # in force at the window's start
        self._pending: tuple[Trigger, str | None, int] | None = None  # trigger, reason, due
        self._last_save_ns: int | None = None
        # the last pose's quality was at or above the threshold (False until it first is: a
        # start-up's identification is no drop)
        self._quality_ok = False
        self._threads: list[threading.Thread] = []
        self.saved: list[Path] = []  # this run's saves, oldest first
        self.on_saved: Callable[[BlackBoxRecording], None] | None = None

    # -- feeding ---------------------------------------------------------------------------
    def add_event(self, event: Event) -> None:
        """An event fed to the localizer (frames, odometry and LED states are kept)."""
        if not isinstance(event, FrameObserved | OdometryMeasured | LedsChanged):
            return
        with self._lock:
            self._events.append(event)
            if isinstance(event, FrameObserved):
                self._frames += 1
            self._trim(event.t_ns)
            self._save_if_due(event.t_ns)

    def add_pose(self, out: PoseEstimate | NoPose) -> None:
        """A pose (or no pose) the localizer answered; a loss, a suspected kidnap or a
        quality drop arms a save."""
        with self._lock:
            self._poses.append(out)
            previous_ok, self._quality_ok = (
                self._quality_ok,
                ((out.quality or 0.0) >= self.config.quality_below),
            )
            if out.mode == "lost" and out.reason == "kidnapped_suspected":
                self._arm("kidnap", out.reason, out.t_ns)
            elif out.mode == "lost":
                self._arm("lost", out.reason, out.t_ns)
            elif isinstance(out, PoseEstimate) and previous_ok and not self._quality_ok:
                self._arm("quality", out.reason, out.t_ns)
            self._save_if_due(out.t_ns)

    def trigger(self, t_ns: int, trigger: Trigger = "operator", reason: str | None = None) -> None:
        """Save the black box around `t_ns` (an operator's click: at once, not rate-limited)."""
        with self._lock:
            self._pending = (trigger, reason, t_ns)

    def save_now(self, trigger: Trigger = "operator", reason: str | None = None) -> Path:
        """Save what is in memory now, and wait for it (the API's action)."""
        with self._lock:
            t_ns = self._latest_t_ns()
            path = self._save(trigger, reason, t_ns)
            threads = list(self._threads)
        for th in threads:
            th.join()
        return path

    def close(self) -> None:
        """Wait for the saves in progress."""
        with self._lock:
            threads, self._threads = self._threads, []
        for th in threads:
            th.join()

    # -- inside ----------------------------------------------------------------------------
    def _arm(self, trigger: Trigger, reason: str | None, t_ns: int) -> None:
        if self._pending is not None:
            return
        last = self._last_save_ns
        if last is not None and (t_ns - last) * _NS < self.config.min_interval_s:
            return
        self._pending = (trigger, reason, t_ns + int(self.config.after_s / _NS))

    def _save_if_due(self, t_ns: int) -> None:
        if self._pending is None or t_ns < self._pending[2]:
            return
        trigger, reason, _ = self._pending
        self._save(trigger, reason, t_ns)

    def _latest_t_ns(self) -> int:
        last = [q[-1].t_ns for q in (self._events, self._poses) if q]
        return max(last, default=0)

    def _trim(self, t_now: int) -> None:
        horizon = t_now - int((self.config.seconds + self.config.after_s) / _NS)
        while self._events and (
            self._events[0].t_ns < horizon or self._frames > self.config.max_frames
        ):
            old = self._events.popleft()
            if isinstance(old, FrameObserved):
                self._frames -= 1
            elif isinstance(old, LedsChanged):
                self._leds_before = old
        while self._poses and self._poses[0].t_ns < horizon:
            self._poses.popleft()

    def _save(self, trigger: Trigger, reason: str | None, t_ns: int) -> Path:
        """Snapshot the memory and write it on a thread; returns the folder."""
        self._pending = None
        self._last_save_ns = t_ns
        stamp = datetime.now(UTC)
        folder = self.root / f"{self.robot}-{stamp.strftime('%Y%m%dT%H%M%S%f')}-blackbox-{trigger}"
        events, poses = list(self._events), list(self._poses)
        meta = {
            "robot": self.robot,
            "trigger": trigger,
            "reason": reason,
            "t_ns": t_ns,
            "saved_at": stamp.isoformat(),
        }
        args = (folder, events, poses, self._leds_before, meta, self._records())
        th = threading.Thread(target=self._write, args=args, name=f"blackbox-{self.robot}")
        self._threads = [t for t in self._threads if t.is_alive()] + [th]
        th.start()
        return folder

    def _write(
        self,
        folder: Path,
        events: list[Event],
        poses: list[PoseEstimate | NoPose],
        leds_before: LedsChanged | None,
        meta: dict[str, Any],
        records: list[dict[str, Any]],
    ) -> None:
        part = folder.with_name(f".{folder.name}.part")  # hidden: no listing shows it
        try:
            write_black_box(part, self.camera, self.geometry, records, events, poses, leds_before)
            (part / META_FILE).write_text(json.dumps(meta, indent=1), encoding="utf-8")
            started = datetime.fromisoformat(str(meta["saved_at"]))
            write_meta(part, self.robot, catalog_trigger(meta["trigger"]), started)
            part.rename(folder)
        except Exception:  # the thread's boundary: whatever failed, log it, leave no half folder
            log.exception("robot %s: black box not saved", self.robot, extra={"robot": self.robot})
            shutil.rmtree(part, ignore_errors=True)
            return
        with self._lock:
            self.saved.append(folder)
        enforce_retention(self.root, self.config.max_bytes)
        if self.on_saved is not None and folder.is_dir():
            info = read_black_box(folder)
            if info is not None:
                self.on_saved(info)


def catalog_trigger(trigger: Trigger) -> str:
    """A black box's `trigger` in the recordings catalog (`GET /recordings?trigger=`)."""
    return f"black_box_{trigger}"


def write_black_box(
    root: Path,
    camera: CameraModel,
    geometry: RobotGeometry,
    landmark_records: Iterable[Mapping[str, Any]],
    events: list[Event],
    poses: list[PoseEstimate | NoPose],
    leds_before: LedsChanged | None,
) -> None:
    """Write events and poses as a recording folder (the LED state in force first, the
    first pose as `start_pose.yaml`)."""
    first_t = min((e.t_ns for e in events), default=0)
    records = list(landmark_records)
    ids = frozenset(int(r["id"]) for r in records)  # a landmark removed since is no more
    with RecordingWriter(root, camera, geometry, records) as rec:
        if leds_before is not None:
            before = only_landmarks(leds_before, ids)
            rec.add_leds(LedsChanged(first_t, before.lit, before.all_lit))
        for e in events:
            if isinstance(e, FrameObserved):
                rec.add_frame(e.t_ns, np.ascontiguousarray(e.image))
            elif isinstance(e, OdometryMeasured):
                rec.add_odometry(e.t_ns, e.v_left, e.v_right)
            elif isinstance(e, LedsChanged):
                rec.add_leds(only_landmarks(e, ids))
        for p in poses:
            rec.add_pose(p)
    start = next((p for p in poses if isinstance(p, PoseEstimate)), None)
    if start is not None:
        prior = {
            "x": float(start.x),
            "y": float(start.y),
            "theta": float(start.theta),
            "timestamp_ns": int(start.t_ns),
        }
        if start.deviation_m is not None and start.deviation_m > 0:
            prior["radius_m"] = float(start.deviation_m)
        (root / START_POSE_FILE).write_text(yaml.safe_dump(prior), encoding="utf-8")


def read_black_box(folder: Path) -> BlackBoxRecording | None:
    """A saved black box's description (None: not a black box, or unreadable)."""
    try:
        meta = json.loads((folder / META_FILE).read_text(encoding="utf-8"))
        trigger = meta["trigger"]
        if trigger not in TRIGGERS:
            return None
        return BlackBoxRecording(
            folder,
            str(meta["robot"]),
            trigger,
            meta.get("reason"),
            int(meta["t_ns"]),
            str(meta["saved_at"]),
            folder_bytes(folder),
        )
    except (OSError, ValueError, KeyError, TypeError):
        return None


def list_black_boxes(root: Path, robot: str | None = None) -> list[BlackBoxRecording]:
    """The black boxes saved under `root` (a robot's, or all), oldest first."""
    if not root.is_dir():
        return []
    found = [read_black_box(p) for p in sorted(root.iterdir()) if (p / META_FILE).is_file()]
    out = [b for b in found if b is not None and (robot is None or b.robot == robot)]
    return sorted(out, key=lambda b: b.saved_at)


def folder_bytes(folder: Path) -> int:
    return sum(f.stat().st_size for f in folder.rglob("*") if f.is_file())


def enforce_retention(root: Path, max_bytes: int) -> list[Path]:
    """Remove the oldest black boxes under `root` until they hold at most `max_bytes`;
    returns the folders removed (other recordings are never touched)."""
    boxes = list_black_boxes(root)
    total = sum(b.bytes for b in boxes)
    removed = []
    for b in boxes:
        if total <= max_bytes:
            break
        shutil.rmtree(b.path, ignore_errors=True)
        total -= b.bytes
        removed.append(b.path)
    return removed
