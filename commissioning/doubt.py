"""Doubted landmarks: the ones localized robots expected to see but did not use.

A landmark is *doubted* when, over its last `DoubtConfig.window` chances, the robots that
should have used it rarely did. A chance is one pose estimate (at most one per robot every
`min_interval_s`) of a robot that

- is localized from landmarks (mode "landmark") with a small position error
  (1-sigma <= `max_sigma_m`) and used at least `min_others` other landmarks in that frame,
- has *settled*: its fixes have lasted `settle_s` since it last identified or was lost (its
  first fixes use the landmarks it identified, before it hands off to the others in view),
- and whose localizer expected the landmark in view and lit at that frame
  (`PoseEstimate.expected_ids`: predicted inside the image, LED surely lit, not being
  switched), within `max_off_axis_rad` of the optical axis (farther off, an LED is too dim
  to detect: its emission and the lens's vignetting fall with that angle) and at least
  `margin_px` inside the image border.

It is doubted once it had at least `min_chances` chances and was used in at most
`max_used_fraction` of its last `window` ones. The localizer matches spots to the map with a
gate, so a landmark whose spot is far from where the map puts it (moved, or surveyed wrong),
a dead or covered LED, or a wrong radio address all end up here. Moving a landmark in the map
forgets its history.

Pure: numpy in, sets out; the caller feeds the localizer's estimates
(`DoubtTracker.observe`, `DoubtTracker.unlocalized`). docs/commissioning.md.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from commissioning.geometry import in_view_camera
from localizer.camera import CameraModel, T_camera_world
from localizer.events import PoseEstimate
from localizer.geometry import T_world_body_from_pose, transform_points
from localizer.types import BoolArray, FloatArray


@dataclass(frozen=True)
class DoubtConfig:
    """When a landmark counts as doubted.

    Attributes:
        window: chances remembered per landmark (frames); as long as `min_chances`, a
            landmark that stops being used (its LED died) is doubted after that many
            chances, whatever its record before.
        min_chances: chances needed before judging a landmark.
        max_used_fraction: doubted when used in at most this share of its chances.
        min_others: a frame counts only when the robot used at least this many other
            landmarks in it (it was localized and seeing).
        max_sigma_m: ... and its 1-sigma position error was at most this, metres.
        margin_px: the LED must project at least this far inside the image border, pixels.
        max_off_axis_rad: ... and be at most this far from the camera's optical axis,
            radians (beyond about 45 degrees the simulated LEDs are too dim to detect).
        settle_s: a robot's frames count once it has had fixes this long since it last
            identified or was lost, seconds.
        moved_m: a map position change larger than this forgets the landmark's history, m.
        min_interval_s: a robot's updates closer together than this are skipped, seconds
            (its frames are highly correlated; this bounds the cost).
    """

    window: int = 60
    min_chances: int = 60
    max_used_fraction: float = 0.1
    min_others: int = 2
    max_sigma_m: float = 0.05
    margin_px: float = 25.0
    max_off_axis_rad: float = math.radians(40.0)
    settle_s: float = 2.0
    moved_m: float = 0.001
    min_interval_s: float = 0.1


@dataclass(frozen=True)
class Doubt:
    """One landmark's record: `chances` frames in which it should have been used, `used`."""

    landmark_id: int
    chances: int
    used: int

    @property
    def reason(self) -> str:
        return f"expected in view {self.chances} times, used {self.used}"


def expected_in_view(
    camera: CameraModel,
    pose: tuple[float, float, float],
    positions: FloatArray,
    *,
    margin_px: float,
    max_off_axis_rad: float = math.pi / 2,
) -> BoolArray:
    """Which landmark positions (N, 3) project into the image, `margin_px` inside its border,
    at most `max_off_axis_rad` from the optical axis, for a body pose (x, y, theta); shape
    (N,)."""
    p = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    if len(p) == 0:
        return np.zeros(0, dtype=bool)
    p_camera = transform_points(T_camera_world(camera, T_world_body_from_pose(*pose)), p)
    return in_view_camera(camera, p_camera, margin_px=margin_px, max_off_axis_rad=max_off_axis_rad)


class DoubtTracker:
    """Counts, per landmark, the chances robots had to use it and whether they did."""

    def __init__(self, config: DoubtConfig | None = None) -> None:
        self.config = config or DoubtConfig()
        self._history: dict[int, deque[bool]] = {}
        self._where: dict[int, FloatArray] = {}
        self._last_t_ns: dict[str, int] = {}
        self._fix_since: dict[str, int] = {}  # first fix since it last had no pose

    def set_map(self, positions: Mapping[int, npt.ArrayLike]) -> None:
        """The map's landmark positions (id -> (3,)); moved or removed landmarks are forgotten."""
        new = {int(k): np.asarray(v, dtype=np.float64).reshape(3) for k, v in positions.items()}
        for lid in list(self._history):
            old, now = self._where.get(lid), new.get(lid)
            if now is None or old is None or np.linalg.norm(now - old) > self.config.moved_m:
                del self._history[lid]
        self._where = new

    def observe(self, robot: str, camera: CameraModel, pose: PoseEstimate) -> None:
        """One robot's estimate for a frame (with the landmarks its localizer expected in
        view and lit, `pose.expected_ids`) and its camera."""
        cfg = self.config
        if pose.mode in ("identifying", "lost"):
            self.unlocalized(robot)
            return
        if pose.mode != "landmark" or not self._where:
            return
        since = self._fix_since.setdefault(robot, pose.t_ns)
        if pose.t_ns - since < cfg.settle_s * 1e9:
            return
        last = self._last_t_ns.get(robot)
        if last is not None and 0 <= pose.t_ns - last < cfg.min_interval_s * 1e9:
            return
        self._last_t_ns[robot] = pose.t_ns
        cov = np.asarray(pose.covariance, dtype=np.float64)
        if math.sqrt(max(0.0, float(cov[0, 0] + cov[1, 1]))) > cfg.max_sigma_m:
            return
        used = set(pose.landmark_ids)
        if len(used) < cfg.min_others:
            return
        ids = [lid for lid in sorted(set(pose.expected_ids)) if lid in self._where]
        if not ids:
            return
        pts = np.array([self._where[i] for i in ids])
        seen = expected_in_view(
            camera,
            (pose.x, pose.y, pose.theta),
            pts,
            margin_px=cfg.margin_px,
            max_off_axis_rad=cfg.max_off_axis_rad,
        )
        for lid, visible in zip(ids, seen, strict=True):
            if not visible or len(used - {lid}) < cfg.min_others:
                continue
            hist = self._history.get(lid)
            if hist is None:
                hist = self._history[lid] = deque(maxlen=cfg.window)
            hist.append(lid in used)

    def unlocalized(self, robot: str) -> None:
        """The robot has no pose (identifying, lost): it settles again after its next fix."""
        self._fix_since.pop(robot, None)

    def record(self, landmark_id: int) -> Doubt:
        """A landmark's chances and uses so far (within the window)."""
        hist = self._history.get(landmark_id, ())
        return Doubt(landmark_id, len(hist), sum(hist))

    def doubted(self) -> dict[int, Doubt]:
        """The doubted landmarks, by ID."""
        cfg = self.config
        out = {}
        for lid in sorted(self._history):
            d = self.record(lid)
            if d.chances >= cfg.min_chances and d.used <= cfg.max_used_fraction * d.chances:
                out[lid] = d
        return out
