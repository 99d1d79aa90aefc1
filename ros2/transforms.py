"""The robot's own `odom -> base_link` over time, as it arrives on `/tf`, looked up at a
frame's stamp (linear interpolation between the two samples around it, as tf2 does; no
extrapolation: a stamp outside the history has no transform)."""

from __future__ import annotations

import bisect
import threading

from ros2.messages import Pose2, wrap


class TransformHistory:
    """T_parent_child samples (stamp ns -> planar pose), the last `keep_s` seconds."""

    def __init__(self, parent: str, child: str, keep_s: float = 10.0) -> None:
        self.parent, self.child = parent, child
        self.keep_ns = round(keep_s * 1e9)
        self._t: list[int] = []
        self._p: list[Pose2] = []
        self._lock = threading.Lock()

    def add(self, t_ns: int, pose: Pose2) -> None:
        with self._lock:
            i = bisect.bisect_left(self._t, t_ns)
            if i < len(self._t) and self._t[i] == t_ns:
                self._p[i] = pose
                return
            self._t.insert(i, t_ns)
            self._p.insert(i, pose)
            cut = bisect.bisect_left(self._t, self._t[-1] - self.keep_ns)
            if cut:
                del self._t[:cut], self._p[:cut]

    @property
    def latest_ns(self) -> int | None:
        with self._lock:
            return self._t[-1] if self._t else None

    def at(self, t_ns: int) -> Pose2 | None:
        """T_parent_child at `t_ns`, or None outside the history."""
        with self._lock:
            if not self._t or t_ns < self._t[0] or t_ns > self._t[-1]:
                return None
            i = bisect.bisect_left(self._t, t_ns)
            if self._t[i] == t_ns:
                return self._p[i]
            t0, t1 = self._t[i - 1], self._t[i]
            a, b = self._p[i - 1], self._p[i]
        s = (t_ns - t0) / (t1 - t0)
        return (
            a[0] + s * (b[0] - a[0]),
            a[1] + s * (b[1] - a[1]),
            wrap(a[2] + s * wrap(b[2] - a[2])),
        )

    def describe_gap(self, t_ns: int) -> str:
        """Why `at(t_ns)` found nothing, in one sentence."""
        with self._lock:
            if not self._t:
                return f"no transform {self.parent} -> {self.child} received on /tf"
            first, last = self._t[0], self._t[-1]
        if t_ns > last:
            return (
                f"no transform {self.parent} -> {self.child} at the frame's stamp: the latest is "
                f"{(t_ns - last) / 1e6:.0f} ms older"
            )
        return (
            f"no transform {self.parent} -> {self.child} at the frame's stamp: the history "
            f"starts {(first - t_ns) / 1e6:.0f} ms after it"
        )
