"""Why a robot has no landmark fix, per robot: the reason now and how many poses each
reason has explained (the robots table, `/metrics`, the `robot_lost` event)."""

from __future__ import annotations

import threading
from collections import Counter

from live.events import EventKind
from live.poses import PoseUpdate
from localizer.pose_quality import ReasonCode


class ReasonTally:
    """The latest reason of a robot's poses, and the poses counted per reason (thread-safe).

    Attributes:
        reason: the latest update's reason code (None: a landmark fix, or none yet).
        reason_text: the same for people.
        quality: the latest update's 0-1 quality (None: none yet, or not known).
        last: the latest update itself (with a pose or without).
    """

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._counts: Counter[str] = Counter()
        self.reason: ReasonCode | None = None
        self.reason_text = ""
        self.quality: float | None = None
        self.last: PoseUpdate | None = None

    def note(self, update: PoseUpdate) -> None:
        """One pose update (with a pose or without)."""
        with self._lock:
            self.reason, self.reason_text = update.reason, update.reason_text
            self.quality, self.last = update.quality, update
            self._counts[update.reason or "landmark_fix"] += 1

    def counts(self) -> dict[str, int]:
        """Poses per reason code ("landmark_fix": those with none), a copy."""
        with self._lock:
            return dict(self._counts)


def mode_change_event(
    robot: str, old: str, new: str, tally: ReasonTally
) -> tuple[EventKind, str, dict[str, object]] | None:
    """The site event of a robot's mode change, (kind, message, data), or None: lost (with
    the reason, e.g. "kidnapped_suspected"), localized again, or identifying again after a
    relocalize (no pose until its landmarks are named again)."""
    if new == "lost":
        reason = tally.reason or "lost"
        text = f": {tally.reason_text}" if tally.reason_text else ""
        return "robot_lost", f"robot {robot} is lost{text}", {"reason": reason}
    if new == "landmark" and old in ("lost", "identifying"):
        return "robot_localized", f"robot {robot} localized", {}
    if new == "identifying" and old in ("landmark", "dead_reckoning"):
        text = f"robot {robot} identifies its landmarks again (no pose until it has)"
        return "robot_identifying", text, {}
    return None
