"""The recordings on disk: listed, zipped for download, deleted, and kept within bounds.

Every recording is a folder `<recordings_dir>/<robot>-<UTC time>/` (EuRoC-style,
docs/recording.md) with `irloc_recording.json` beside the data: which robot, when it began,
why it was made (`trigger`: "manual" for the API and viewer's start, "survey" for a live
survey's drive; other kinds may follow). A recording a robot is still writing is listed
with `live` true and cannot be deleted. Retention (`prune`) removes the oldest finished
recordings beyond an age or a total size; a cancelled survey's recording is removed at once
(`delete`, by the survey).

Names are only ever matched against the folders listed (never joined to a path as given),
so a crafted name cannot reach outside the recordings folder.
"""

from __future__ import annotations

import builtins
import json
import logging
import os
import shutil
import tempfile
import threading
import zipfile
from collections.abc import Callable
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta
from pathlib import Path

from recording import layout
from store.errors import ConflictError, NotFoundError

log = logging.getLogger(__name__)
META_FILE = "irloc_recording.json"


@dataclass(frozen=True)
class RecordingInfo:
    """One recording folder.

    Attributes:
        name: the folder's name (the recording's ID in the API).
        robot: the robot recorded.
        started: when it began, UTC.
        trigger: why it was made ("manual", "survey", ...).
        live: a robot is still writing it.
        size_bytes: its files' total size.
        frames: camera frames in it.
    """

    name: str
    robot: str
    started: datetime
    trigger: str
    live: bool
    size_bytes: int
    frames: int


def write_meta(root: Path, robot: str, trigger: str, started: datetime) -> None:
    """Write a new recording's `irloc_recording.json` (the folder exists)."""
    meta = {"robot": robot, "trigger": trigger, "started": started.isoformat()}
    root.mkdir(parents=True, exist_ok=True)
    (root / META_FILE).write_text(json.dumps(meta), encoding="utf-8")


class RecordingCatalog:
    """The recordings under `root` (thread-safe).

    Args:
        root: the recordings folder.
        live: returns the folders robots are writing now.
        keep_days: finished recordings older than this are removed by `prune` (None: kept).
        max_total_bytes: the oldest finished recordings are removed by `prune` until the
            rest fit (None: no bound).
    """

    def __init__(
        self,
        root: Path,
        live: Callable[[], set[Path]],
        *,
        keep_days: float | None = 30.0,
        max_total_bytes: int | None = 20 * 1024**3,
    ) -> None:
        self.root, self._live = root, live
        self.keep_days, self.max_total_bytes = keep_days, max_total_bytes
        self._lock = threading.Lock()

    # -- reading -----------------------------------------------------------------------------
    def list(self, robot: str | None = None) -> list[RecordingInfo]:
        """Every recording (of `robot`), newest first."""
        if not self.root.is_dir():
            return []
        live = {p.resolve() for p in self._live()}
        out = [
            self._info(d, d.resolve() in live)
            for d in self.root.iterdir()
            if d.is_dir() and not d.name.startswith(".")
        ]
        if robot is not None:
            out = [r for r in out if r.robot == robot]
        return sorted(out, key=lambda r: (r.started, r.name), reverse=True)

    def get(self, name: str) -> RecordingInfo:
        """One recording by name; NotFoundError naming the ones there are."""
        for info in self.list():
            if info.name == name:
                return info
        names = [r.name for r in self.list()][:10]
        raise NotFoundError(
            f"no recording {name!r}; recordings: {', '.join(names) or 'none'}"
            + (" ..." if len(names) == 10 else "")
        )

    def _info(self, folder: Path, live: bool) -> RecordingInfo:
        robot, _, stamp = folder.name.rpartition("-")
        started = _parse_stamp(stamp) or datetime.fromtimestamp(folder.stat().st_mtime, UTC)
        trigger = "manual"
        try:
            meta = json.loads((folder / META_FILE).read_text(encoding="utf-8"))
            robot = str(meta.get("robot", robot))
            trigger = str(meta.get("trigger", trigger))
            started = datetime.fromisoformat(str(meta["started"]))
        except (OSError, ValueError, KeyError, TypeError):
            pass  # an older recording or one copied in by hand: read from its name
        size = 0
        for base, _, files in os.walk(folder):
            for f in files:
                try:
                    size += os.stat(os.path.join(base, f)).st_size
                except OSError:
                    continue
        try:
            with open(folder / layout.FRAMES_FILE, encoding="utf-8") as fh:
                frames = sum(1 for line in fh if line.strip() and not line.startswith("#"))
        except OSError:
            frames = 0
        return RecordingInfo(
            folder.name, robot or folder.name, started, trigger, live, size, frames
        )

    # -- download ----------------------------------------------------------------------------
    def zip_file(self, name: str) -> Path:
        """The recording as a zip in a temporary file (the caller deletes it): stored, not
        compressed (the frames are PNG already). ConflictError while it is being written."""
        info = self.get(name)
        if info.live:
            raise ConflictError(f"recording {name} is still being written: stop it first")
        folder = self.root / info.name
        fd, tmp = tempfile.mkstemp(prefix=f".{info.name}.", suffix=".zip", dir=self.root)
        os.close(fd)
        try:
            with zipfile.ZipFile(tmp, "w", compression=zipfile.ZIP_STORED) as zf:
                for base, _, files in os.walk(folder):
                    for f in sorted(files):
                        path = Path(base) / f
                        zf.write(path, Path(info.name) / path.relative_to(folder))
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise
        return Path(tmp)

    # -- removal -----------------------------------------------------------------------------
    def delete(self, name: str) -> RecordingInfo:
        """Delete a finished recording; ConflictError while a robot writes it."""
        with self._lock:
            info = self.get(name)
            if info.live:
                raise ConflictError(f"recording {name} is still being written: stop it first")
            shutil.rmtree(self.root / info.name)
        log.info("recording %s deleted (%d bytes)", name, info.size_bytes)
        return info

    def prune(self, now: datetime | None = None) -> builtins.list[str]:
        """Remove finished recordings older than `keep_days`, then the oldest until the
        rest fit in `max_total_bytes`; the names removed."""
        now = now or datetime.now(UTC)
        gone: builtins.list[str] = []
        done = [r for r in self.list() if not r.live]  # newest first
        if self.keep_days is not None:
            cutoff = now - timedelta(days=self.keep_days)
            gone += [r.name for r in done if r.started < cutoff]
        if self.max_total_bytes is not None:
            total = sum(r.size_bytes for r in self.list())
            for r in reversed(done):  # oldest first
                if total <= self.max_total_bytes:
                    break
                if r.name not in gone:
                    gone.append(r.name)
                total -= r.size_bytes
        for name in gone:
            try:
                self.delete(name)
            except (ConflictError, NotFoundError, OSError) as exc:
                log.warning("recordings: could not remove %s: %s", name, exc)
        if gone:
            log.info("recordings: removed %s (retention)", ", ".join(gone))
        return gone


def _parse_stamp(stamp: str) -> datetime | None:
    try:
        return datetime.strptime(stamp, "%Y%m%dT%H%M%S").replace(tzinfo=UTC)
    except ValueError:
        return None
