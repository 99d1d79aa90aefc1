"""The samples of one target (docs/commissioning.md): its frames placed on the ceiling over
the last `keep_s`, the spot that followed its LED in each lit frame
(`commissioning.measuring.switched_spot`), and whether the latest samples agree. Sans-I/O:
frames in, in time order; values out."""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Sequence

from commissioning.measuring import (
    Agreement,
    PlacedFrame,
    agreement,
    switch_record,
    switched_spot,
)
from commissioning.wizard_config import WizardConfig
from localizer.camera import CameraModel
from localizer.types import FloatArray


class TargetSamples:
    """What one robot's frames tell of where one target's LED is.

    Attributes:
        frames: the kept frames (the last `keep_s`), time order.
        points: the samples, world frame, metres, each shape (3,) (the last few).
        pairs: lit frames that had a dark frame to compare with.
        ambiguous: ... of which more than one spot followed the target (reflections).
        flickering: where the last spot that came and went out of step with the target was
            (x, y), metres, unless at a landmark of the map (a robot's probe, or a landmark
            at the edge of detection, are no news); None: none did.
        agreed: the latest agreement of `min_agreeing` samples (None: none yet).
        pixel, frame_ns: the target's spot in the latest lit frame that gave a sample.
    """

    def __init__(
        self,
        camera: CameraModel,
        config: WizardConfig,
        landmarks_xy: Sequence[tuple[float, float]],
    ) -> None:
        """`landmarks_xy`: the other landmarks of the map, (x, y) metres."""
        self.camera, self.config = camera, config
        self._landmarks_xy = tuple(landmarks_xy)
        self.frames: deque[PlacedFrame] = deque()
        self.points: list[FloatArray] = []
        self.pairs = 0
        self.ambiguous = 0
        self.flickering: tuple[float, float] | None = None
        self.agreed: Agreement | None = None
        self.pixel: tuple[float, float] | None = None
        self.frame_ns = 0
        self.horizon_ns = 0  # frames before this are forgotten

    def add(self, frame: PlacedFrame) -> None:
        """Take the next frame (an older or repeated one is ignored)."""
        cfg = self.config
        if self.frames and frame.t_ns <= self.frames[-1].t_ns:
            return
        self.frames.append(frame)
        self.horizon_ns = self._horizon(frame.t_ns)
        while self.frames[0].t_ns < self.horizon_ns:
            self.frames.popleft()
        match = {"match_m": cfg.match_m, "margin_px": cfg.margin_px}
        if not frame.target_on:
            # a spot where it was measured, shown while it is dark: that was no switch
            a = self.agreed
            if a is not None and switch_record(self.camera, a.position, [frame], **match).extras:
                self.agreed, self.points = None, []
            return
        found = switched_spot(self.camera, self.frames, **match, min_cycles=cfg.min_cycles)
        if found is None:
            return
        self.pairs += 1
        self.ambiguous += found.switched > 1
        for fx, fy in found.flickering:
            if all(math.hypot(fx - x, fy - y) > cfg.match_m for x, y in self._landmarks_xy):
                self.flickering = (fx, fy)
        if found.point is None:
            return
        self.points.append(found.point)
        del self.points[: -4 * cfg.min_agreeing]
        self.pixel, self.frame_ns = found.pixel, frame.t_ns
        agreed = agreement(self.points, agree_m=cfg.agree_m, needed=cfg.min_agreeing)
        if agreed is not None:
            self.agreed = agreed

    def _horizon(self, now_ns: int) -> int:
        """Frames before this are forgotten: those older than `keep_s`, unless among the
        last 2 `min_cycles` phases of the target's LED (the LED coordinator may stretch a
        phase while robots take their turns), and those older than `max_keep_s`."""
        cfg = self.config
        keep = now_ns - round(cfg.keep_s * 1e9)
        runs, previous, start = 0, None, now_ns
        for f in reversed(self.frames):
            if f.target_on != previous:
                runs, previous = runs + 1, f.target_on
                if runs > 2 * cfg.min_cycles:
                    break
            start = f.t_ns
        return max(min(keep, start), now_ns - round(cfg.max_keep_s * 1e9))
