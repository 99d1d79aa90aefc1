"""A robot's trail in the 3D scene: its poses as line pieces, only the newest resent, a jump
in distance or time not joined, the oldest dropped beyond a bound."""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import numpy as np
import viser

from web.colors import RGB
from web.segments import polyline_segments, set_segments

TRAIL_COLOR: RGB = (90, 90, 200)


@dataclass(frozen=True)
class TrailConfig:
    """How a robot's trail samples its poses.

    Attributes:
        min_step_m: a pose is added once the robot moved this far from the last point,
            metres (a robot standing still adds nothing; the trail follows the floor, not
            the viewer's update rate).
        max_jump_m: two consecutive points farther apart than this are not joined, metres
            (a gap in the poses: a busy server, a robot lost and found again; joined, they
            would draw a chord through the walls).
        max_gap_s: ... nor two points further apart in time than this, seconds.
        max_points: points kept (the oldest pieces are dropped beyond it).
        piece: points per trail piece: only the newest piece is resent.
    """

    min_step_m: float = 0.1
    max_jump_m: float = 1.0
    max_gap_s: float = 5.0
    max_points: int = 600
    piece: int = 20


class Trail:
    """A robot's trail as pieces of at most `piece` points, in the robot's colour: finished
    pieces stay in the scene as they are, only the newest is resent; the oldest go beyond
    `max_points`. A jump in distance or time starts a new piece not joined to the last."""

    def __init__(
        self,
        scene: viser.SceneApi,
        root: str,
        *,
        color: RGB = TRAIL_COLOR,
        config: TrailConfig | None = None,
    ) -> None:
        self.scene, self.root, self.color = scene, root, color
        self.config = cfg = config or TrailConfig()
        self.piece = max(2, cfg.piece)
        self._pieces: deque[tuple[viser.LineSegmentsHandle, int]] = deque()
        self._points: list[tuple[float, float]] = []
        self._last: tuple[float, float, float] | None = None  # x, y, t seconds
        self._k = 0
        self.shown: deque[tuple[float, float]] = deque(maxlen=cfg.max_points)
        """The points drawn (about; for tests), oldest first."""

    def append(self, x: float, y: float, t_s: float) -> bool:
        """Offer a pose (world x, y metres at time `t_s` seconds); True when it was added
        (it moved `min_step_m` since the last point), then the newest piece is resent."""
        cfg = self.config
        last = self._last
        if last is not None:
            step = math.hypot(x - last[0], y - last[1])
            if step < cfg.min_step_m and t_s >= last[2]:
                return False
            if step > cfg.max_jump_m or abs(t_s - last[2]) > cfg.max_gap_s:
                self._points = []  # a gap: the next piece starts here, not joined
        self._last = (x, y, t_s)
        if len(self._points) >= self.piece:  # finish this piece; the next starts at its end
            self._points = self._points[-1:]
            self._pieces.append((self._new_piece(), 0))
        elif not self._points:
            self._pieces.append((self._new_piece(), 0))
        self._points.append((x, y))
        self.shown.append((x, y))
        handle, _ = self._pieces[-1]
        self._pieces[-1] = (handle, len(self._points))
        while sum(n for _, n in self._pieces) > cfg.max_points and len(self._pieces) > 1:
            self._pieces.popleft()[0].remove()
        p = np.array(self._points)
        seg = polyline_segments(np.column_stack([p, np.full(len(p), 0.01)]))
        set_segments(handle, seg, self.color)
        return True

    def _new_piece(self) -> viser.LineSegmentsHandle:
        self._k += 1
        return self.scene.add_line_segments(
            f"{self.root}/{self._k}", np.zeros((0, 2, 3)), self.color, thickness=0.05
        )

    @property
    def pieces(self) -> list[viser.LineSegmentsHandle]:
        """The trail's nodes, oldest first."""
        return [h for h, _ in self._pieces]
