"""Re-seeding the filter from a run of fixes the odometry disagrees with.

A robot stuck against a pallet with its wheels turning, a wheel spinning on a wet floor, a
bump: the odometry says the robot moved where it did not, the filter's prediction follows
it, and every fix, however good, fails the innovation gate (`PoseFilter.update_fix`) while
the dead reckoning drives the pose away. Widening the prediction until the fixes pass is the
loose gate (a glint beside a landmark then fits as well). The camera, not the odometry, is
the truth when many landmarks agree, and agree with each other frame after frame: the fixes
rejected by the filter are kept as a run, and once `FixRunConfig.min_fixes` of them in a row
form one physically possible track, the filter is re-seeded at the newest (and at every one
after it while the track goes on).

A run is accepted only when it is a track the robot could have driven without any help from
the odometry (`fixes_linked`): every fix of `min_landmarks` or more landmarks, each within
reach (maximum speed and turn rate x the time between them, plus `link_gate_chi2` of their
uncertainty) of the one before, the first within reach of the last fused fix (the anchor),
each sharing most of its landmarks with the one before. A link whose reach is half the
landmark spacing or more proves nothing (a pose one grid spacing off, the classic ambiguity,
would pass it): the run is then not anchored and the localizer goes on as before (dead
reckoning, lost, re-localization with its own ambiguity test).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from localizer.geometry import wrap_angle
from localizer.pose import PoseFix
from localizer.types import FloatArray, Pose


@dataclass(frozen=True)
class FixRunConfig:
    """Tuning of the re-seeding from a run of rejected fixes (`FixRun`).

    Attributes:
        enabled: re-seed from such a run (False, the default: a rejected fix is only
            rejected). Off by default: on the robustness matrix's `grid40_kidnap_leds` (a
            robot lifted, carried and turned under a 40 cm grid) the fixes of the carry
            chained and re-seeded the filter to a pose 2.1 m and 123 deg off (recovery
            1.1 -> 3.6 s, 6 dead-reckoning frames over 25 cm); what it buys, a stall with
            the wheels turning under a dense ceiling (`bench/foreign` `stuck_wheels` p95
            17.4 -> 0.9 cm), does not outweigh a wrong pose.
        min_landmarks: a fix of fewer landmarks does not count toward a run: with few, one
            glint taken for a landmark moves the fix (with many the robust fit leaves it
            out), and a tilt the floor model does not know passes for a translation. On the
            matrix's `disturbed_real` (a 1.2 m grid, a 2 cm bump under the wheels) fixes of
            6-9 landmarks claiming 0.7 cm were 2-8 cm off, frame to frame inconsistent, and
            with 6 one of them (7 cm off) re-seeded the filter; a stall under a dense
            ceiling has 36-50 (`bench/foreign` `stuck_wheels`).
        min_fixes: the run's length (frames in a row, after the anchor) before the filter is
            re-seeded.
        link_gate_chi2: two fixes are linked when what separates them beyond the robot's
            reach is within this chi-square (2 dof: position and heading) of their
            covariances (13.8: the 99.9 % point).
        min_shared_fraction: a fix shares at least this share of its landmarks with the one
            before (the anchor's landmarks for the first).
        max_reach_spacing: a link is only made when the robot's reach between the two fixes
            plus three of their position sigmas is under this share of the landmark spacing.
    """

    enabled: bool = False
    min_landmarks: int = 12
    min_fixes: int = 3
    link_gate_chi2: float = 13.8
    min_shared_fraction: float = 0.5
    max_reach_spacing: float = 0.5

    def __post_init__(self) -> None:
        if self.min_landmarks < 3:
            raise ValueError(f"FixRunConfig: min_landmarks must be >= 3, got {self.min_landmarks}")
        if self.min_fixes < 1:
            raise ValueError(f"FixRunConfig: min_fixes must be >= 1, got {self.min_fixes}")
        for name in ("link_gate_chi2", "max_reach_spacing"):
            v = getattr(self, name)
            if not math.isfinite(v) or v <= 0:
                raise ValueError(f"FixRunConfig: {name} must be > 0, got {v!r}")
        share = self.min_shared_fraction
        if not 0 <= share <= 1:
            raise ValueError(f"FixRunConfig: min_shared_fraction must be in [0, 1], got {share}")


@dataclass(frozen=True)
class TrackPoint:
    """A pose of the camera's own track: a fix, or the filter's pose at a fused fix.

    Attributes:
        t_ns: its time, nanoseconds.
        pose: (x, y, theta), metres and radians.
        covariance: of the pose, shape (3, 3).
        landmark_ids: the landmarks it was fixed from.
    """

    t_ns: int
    pose: Pose
    covariance: FloatArray
    landmark_ids: frozenset[int]


def fixes_linked(
    a: TrackPoint,
    b: TrackPoint,
    *,
    max_speed_m_s: float,
    max_turn_rad_s: float,
    spacing_m: float,
    config: FixRunConfig,
) -> bool:
    """Could the robot have gone from `a` to `b` by itself, unambiguously?

    With reach r = v_max dt and turn w_max dt over dt = t_b - t_a, the excess
    e_p = max(|p_b - p_a| - r, 0) and e_th = max(|th_b - th_a| - w_max dt, 0) must satisfy
    e_p^2 / (s_a^2 + s_b^2) + e_th^2 / (var_th_a + var_th_b) <= `link_gate_chi2`, with s the
    largest position sigma of each; and r + 3 sqrt(s_a^2 + s_b^2) must stay under
    `max_reach_spacing` x `spacing_m` (else a pose one spacing away would link as well).
    They must also share `min_shared_fraction` of b's landmarks.
    """
    dt = (b.t_ns - a.t_ns) * 1e-9
    if dt <= 0:
        return False
    s2 = _largest_position_variance(a.covariance) + _largest_position_variance(b.covariance)
    reach = max_speed_m_s * dt
    if reach + 3.0 * math.sqrt(s2) >= config.max_reach_spacing * spacing_m:
        return False
    shared = len(a.landmark_ids & b.landmark_ids)
    if shared < config.min_shared_fraction * len(b.landmark_ids):
        return False
    moved = math.hypot(b.pose[0] - a.pose[0], b.pose[1] - a.pose[1])
    turned = abs(float(wrap_angle(b.pose[2] - a.pose[2])))
    e_p = max(moved - reach, 0.0)
    e_th = max(turned - max_turn_rad_s * dt, 0.0)
    var_th = float(a.covariance[2, 2] + b.covariance[2, 2])
    chi2 = e_p * e_p / max(s2, 1e-12) + e_th * e_th / max(var_th, 1e-12)
    return chi2 <= config.link_gate_chi2


def _largest_position_variance(cov: FloatArray) -> float:
    """The larger eigenvalue of the (x, y) block of a pose covariance, m^2."""
    a, b, d = float(cov[0, 0]), float(cov[0, 1]), float(cov[1, 1])
    return 0.5 * (a + d) + math.hypot(0.5 * (a - d), b)


class FixRun:
    """The run of rejected fixes since the last fused one (see the module docstring).

    Args:
        config: tuning.
        max_speed_m_s: the robot's top speed.
        max_turn_rad_s: its fastest turn.
        spacing_m: the map's landmark spacing (median nearest-neighbour distance).
    """

    def __init__(
        self,
        config: FixRunConfig,
        *,
        max_speed_m_s: float,
        max_turn_rad_s: float,
        spacing_m: float,
    ) -> None:
        self.config = config
        self.max_speed_m_s = max_speed_m_s
        self.max_turn_rad_s = max_turn_rad_s
        self.spacing_m = spacing_m
        self._anchor: TrackPoint | None = None
        self._run: list[TrackPoint] = []
        self.accepted = False  # the run has re-seeded the filter and goes on
        self._agreeing = 0  # fixes fused in a row since the last re-seed

    def clear(self) -> None:
        """Forget the anchor and the run (the pose was reset another way)."""
        self._anchor = None
        self._run = []
        self.accepted = False

    def fused(self, t_ns: int, pose: Pose, covariance: FloatArray, ids: tuple[int, ...]) -> None:
        """A fix was fused: the filter's pose then is the new anchor. The run starts over;
        an accepted one stays accepted until `min_fixes` fixes in a row (each linked to the
        one before) have been fused: the odometry is trusted again as it was distrusted
        (in a stall the slip hypothesis, sized by the travel since the last fix, lets a fix
        or two through just after a re-seed)."""
        point = TrackPoint(t_ns, pose, covariance, frozenset(ids))
        if self.accepted:
            before = self._run[-1] if self._run else self._anchor
            self._agreeing += 1
            if (
                before is None
                or not self._linked(before, point)
                or self._agreeing >= self.config.min_fixes
            ):
                self.accepted = False
        self._anchor = point
        self._run = [point] if self.accepted else []

    def offer(self, t_ns: int, fix: PoseFix) -> bool:
        """A fix the filter rejected; True when the filter should be re-seeded at it (it
        completes, or continues, an accepted run)."""
        c = self.config
        if not c.enabled or self._anchor is None:
            return False
        point = TrackPoint(
            t_ns, (fix.x, fix.y, fix.theta), fix.covariance, frozenset(fix.landmark_ids)
        )
        before = self._run[-1] if self._run else self._anchor
        if fix.n_landmarks < c.min_landmarks or not self._linked(before, point):
            # The track is broken: a later fix may still link to the anchor (if within an
            # unambiguous reach of it; the last re-seeded fix, if the run was accepted).
            if self.accepted and self._run:
                self._anchor = self._run[-1]
            self._run = []
            self.accepted = False
            return False
        self._run.append(point)
        if self.accepted or len(self._run) >= c.min_fixes:
            self.accepted = True
            self._agreeing = 0
            return True
        return False

    def _linked(self, a: TrackPoint, b: TrackPoint) -> bool:
        return fixes_linked(
            a,
            b,
            max_speed_m_s=self.max_speed_m_s,
            max_turn_rad_s=self.max_turn_rad_s,
            spacing_m=self.spacing_m,
            config=self.config,
        )
