"""What tracking learnt of each mapped landmark: lit, dark, or unknown; and so what its
absence is worth to a pose hypothesis while the robot is lost.

A hypothesis that predicts a mapped landmark well in view where the image shows no spot
(`hypothesis_scoring.missing_landmarks`) is less likely than one that predicts nothing
there by the probability of that frame showing no spot if the hypothesis is right:

    P(no spot) = p_dark + (1 - p_dark) m,    weight = -ln P(no spot)

with m the probability that a lit landmark predicted well in view is not detected on a
frame, and p_dark the probability that the landmark is dark or hidden now. Nothing known of
a landmark, p_dark is the pessimistic `dark_prior` (a dead LED or a person weighs as much
as a gap in the map: the weight is small). While the robot was tracking, though, each
landmark predicted well in view on a fused frame was either detected (it is lit:
p_dark = `dark_after_lit`, it may have failed or be hidden since) or not; one predicted on
n frames and never detected is dark by Bayes' rule,

    p_dark = dark_prior / (dark_prior + (1 - dark_prior) m^n),

and its absence is no evidence against anyone (the weight tends to 0). m itself is the rate
on the tracked frames (lit landmarks predicted well in view and not detected), with the
prior `miss_prior` weighing `miss_prior_weight` landmark-frames.

A pose and its twin on a symmetric grid both explain every spot: only the landmarks one
predicts where the other predicts none tell them apart, and a landmark seen lit before the
robot got lost says much more by its absence than one nobody has seen (a dead LED: known
dark when it was in view while tracking, unknown, and weighing little, otherwise).
"""

from __future__ import annotations

import numpy as np

from localizer.camera import CameraModel, predict_pixels
from localizer.geometry import T_world_body_from_pose
from localizer.hypothesis_scoring import seen_radius_px, well_in_view
from localizer.relocalization import RelocalizationConfig
from localizer.types import FloatArray, IntArray


class LandmarkLiveness:
    """Per mapped landmark, what the tracked frames showed of it (see the module docstring).

    Args:
        n_landmarks: the map's size (rows are map rows).
        config: `dark_prior`, `dark_after_lit`, `miss_prior`, `miss_prior_weight`.

    Attributes:
        lit: detected on a tracked frame, shape (N,).
        unseen: tracked frames it was predicted well in view on and not detected, while it
            was never detected, shape (N,).
        in_view: landmark-frames of landmarks known lit predicted well in view.
        missed: of those, not detected.
    """

    def __init__(self, n_landmarks: int, config: RelocalizationConfig) -> None:
        self.config = config
        self.lit = np.zeros(n_landmarks, dtype=bool)
        self.unseen = np.zeros(n_landmarks, dtype=np.int64)
        self.in_view = 0
        self.missed = 0

    def observe(self, rows_in_view: IntArray, rows_detected: IntArray) -> None:
        """One tracked frame: the map rows predicted well in view, and those detected
        (fused); a row detected for the first time turns its earlier unseen frames into
        misses of a lit landmark."""
        seen = np.zeros(len(self.lit), dtype=bool)
        seen[np.asarray(rows_detected, dtype=np.int64)] = True
        view = np.zeros(len(self.lit), dtype=bool)
        view[np.asarray(rows_in_view, dtype=np.int64)] = True
        new = seen & ~self.lit
        self.in_view += int(np.sum(self.unseen[new]))
        self.missed += int(np.sum(self.unseen[new]))
        self.unseen[new] = 0
        self.lit |= seen
        lit_view = view & self.lit
        self.in_view += int(np.count_nonzero(lit_view))
        self.missed += int(np.count_nonzero(lit_view & ~seen))
        self.unseen[view & ~self.lit] += 1

    def observe_frame(
        self,
        camera: CameraModel,
        pose: tuple[float, float, float],
        positions: FloatArray,
        rows_predicted: IntArray,
        rows_detected: IntArray,
        detected_px: FloatArray,
    ) -> None:
        """`observe` a fused frame: of the rows predicted in the image, those the pose
        places well in view (`hypothesis_scoring.well_in_view`, within the radius the
        detected spots `detected_px` (K, 2) reach); `positions` is the map's, (N, 3)."""
        rows = np.asarray(rows_predicted, dtype=np.int64)
        if not len(rows) or not len(detected_px):
            return
        px, valid = predict_pixels(camera, T_world_body_from_pose(*pose), positions[rows])
        inner = well_in_view(camera, px, valid, seen_radius_px(camera, detected_px), self.config)
        self.observe(rows[inner], rows_detected)

    def miss_rate(self) -> float:
        """m: the probability that a lit landmark predicted well in view is not detected
        (posterior mean; the prior `miss_prior` weighs `miss_prior_weight`)."""
        c = self.config
        return (self.missed + c.miss_prior * c.miss_prior_weight) / (
            self.in_view + c.miss_prior_weight
        )

    def miss_log_lr(self) -> FloatArray:
        """Each landmark's weight against a hypothesis that predicts it well in view where
        no spot is: -ln(p_dark + (1 - p_dark) m), shape (N,) (module docstring)."""
        c = self.config
        m = self.miss_rate()
        prior = c.dark_prior
        dark = prior / (prior + (1.0 - prior) * np.power(m, self.unseen.astype(np.float64)))
        dark = np.where(self.lit, c.dark_after_lit, dark)
        out: FloatArray = -np.log(dark + (1.0 - dark) * m)
        return out
