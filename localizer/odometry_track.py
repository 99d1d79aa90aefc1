"""The localizer's dead-reckoning track: wheel-speed samples in, the raw odometry pose out.

The localizer integrates odometry twice: the filter's estimate (`PoseFilter.predict`) and a
raw pose by odometry alone, whose recent history carries an identified landmark's sighting to
a later frame's time (first fix) and bounds a spot's image motion between two times. This
module holds the raw side and the bookkeeping of time: the last sample and its speeds, and
each interval's speeds.

A sample reports each wheel's mean speed over the interval since the previous sample (what
encoders measure, and what docs/recording.md specifies), so the wheels ran at the new
sample's speeds over that whole interval (`interval_mean=True`; False: at the mean of the
speeds at the interval's two ends, for odometry that reports instantaneous speeds). Past the
last sample (up to a frame's time) the pose is extrapolated at that sample's speeds; frames
marked meanwhile are corrected when the next sample tells what the wheels really did. Each
interval is integrated exactly (`integrate_arc`, eqs. 5-6 without the chord error).
"""

from __future__ import annotations

from collections import deque

from localizer.odometry import integrate_arc
from localizer.types import Pose

_NS = 1e-9


class OdometryTrack:
    """Raw dead reckoning and its history (SI units, times in integer nanoseconds).

    Args:
        wheel_base_m: distance between the wheels, metres.
        history_s: how long past poses are kept for `pose_at`, seconds.
        interval_mean: samples are mean speeds over the interval before them (else
            instantaneous speeds, integrated by the trapezoid rule).

    Attributes:
        t_state_ns: time the state has been integrated to (None before the first event).
        t_sample_ns: time of the last wheel-speed sample (None before the first).
        speeds: (left, right) wheel speeds of the last sample, m/s.
        pose: the raw odometry pose (x, y, theta) at `t_state_ns`, from (0, 0, 0).
        interval_s: the latest interval between two samples, seconds (None before two).
    """

    def __init__(
        self, wheel_base_m: float, history_s: float, *, interval_mean: bool = True
    ) -> None:
        self.wheel_base = wheel_base_m
        self.interval_mean = interval_mean
        self._horizon_ns = int(history_s / _NS)
        self.t_state_ns: int | None = None
        self.t_sample_ns: int | None = None
        self.speeds = (0.0, 0.0)
        self.pose: Pose = (0.0, 0.0, 0.0)
        self.interval_s: float | None = None
        self._history: deque[tuple[int, float, float, float]] = deque()
        self._at_sample: Pose = self.pose  # the pose at the last sample
        self._marks: list[int] = []  # frame times marked since the last sample

    def step(self, t_ns: int, v_left: float, v_right: float) -> float:
        """Integrate the raw pose to `t_ns` at constant wheel speeds (m/s).

        Returns:
            The step, seconds; 0 (nothing done) when `t_ns` is not after the state's time.
        """
        if self.t_state_ns is None:
            self.t_state_ns = t_ns
        dt = (t_ns - self.t_state_ns) * _NS
        if dt <= 0:
            return 0.0
        x, y, th = self.pose
        self.pose = integrate_arc(x, y, th, v_left, v_right, dt, self.wheel_base)
        self.t_state_ns = t_ns
        return dt

    def add_sample(self, t_ns: int, v_left: float, v_right: float) -> tuple[float, float, float]:
        """A wheel-speed sample: integrate its interval and remember the pose.

        Returns:
            (left speed, right speed, step in seconds) of the interval just integrated (the
            trapezoid speeds; the sample's own speeds for the first sample), for the filter.
        """
        t0 = self.t_sample_ns
        if t0 is None or self.interval_mean:
            vl, vr = v_left, v_right
        else:
            vl, vr = (self.speeds[0] + v_left) / 2, (self.speeds[1] + v_right) / 2
        history = self._history
        if t0 is not None and t_ns > t0:
            # Redo the interval from the last sample: the frames marked in it were placed
            # at the old speeds.
            x0, y0, th0 = self._at_sample
            if self._marks:
                # the marks are the newest entries: replace them
                while len(history) > 1 and history[-1][0] > t0:
                    history.pop()
                for tm in self._marks:
                    if t0 < tm <= t_ns:
                        p = integrate_arc(x0, y0, th0, vl, vr, (tm - t0) * _NS, self.wheel_base)
                        history.append((tm, *p))
            self.pose = integrate_arc(x0, y0, th0, vl, vr, (t_ns - t0) * _NS, self.wheel_base)
            self.interval_s = (t_ns - t0) * _NS
        dt = 0.0 if t0 is None else max((t_ns - t0) * _NS, 0.0)
        self._marks = []
        self.t_state_ns = t_ns
        self._at_sample = self.pose
        self.speeds = (v_left, v_right)
        self.t_sample_ns = t_ns
        history.append((t_ns, *self.pose))
        horizon = t_ns - self._horizon_ns
        while len(history) > 2 and history[1][0] < horizon:
            history.popleft()
        return vl, vr, dt

    def mark(self, t_ns: int) -> None:
        """Remember the current pose at `t_ns` (a frame's time, after `step` to it); a mark
        past the last sample is corrected by the next sample."""
        self._history.append((t_ns, *self.pose))
        if self.t_sample_ns is not None and t_ns > self.t_sample_ns:
            self._marks.append(t_ns)

    def pose_at(self, t_ns: int) -> Pose:
        """Raw odometry pose at `t_ns`: the latest remembered one at or before it (the
        earliest one when `t_ns` precedes them all, the current one without history)."""
        best = self.pose
        for t, x, y, th in reversed(self._history):
            if t <= t_ns:
                return (x, y, th)
            best = (x, y, th)
        return best
