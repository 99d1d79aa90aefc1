"""How `pose.solve_pose` fits: `PoseSolveConfig`."""

from __future__ import annotations

from dataclasses import dataclass

from localizer.pose_planar import RobustLoss


@dataclass(frozen=True, slots=True)
class PoseSolveConfig:
    """Tuning of `solve_pose` (the per-call data, the spots, their sigmas, a start pose and
    a carried floor, are its arguments).

    Attributes:
        estimate_tilt: with 3+ landmarks also consider a tilted body (roll, pitch), and use
            it when it explains the spots significantly better (see `tilt_min_chi2_drop`);
            ignored with fewer landmarks. Tilt and translation are nearly interchangeable for
            a small cluster of landmarks (a tilt a moves every spot like a translation of
            about (ceiling - camera height) a), so a tilted fit is far noisier than a level
            one: with 0.3 px noise and 3-4 landmarks within ~1 m at 2.5 m, several cm against
            ~2 mm. Hence the test, and the recommendation to catch floor bumps primarily with
            the filter's innovation gate.
        tilt_sigma_rad: optional zero-mean prior on roll and pitch, radians (None: no prior;
            not used on a carried floor, whose prior it is).
        tilt_min_chi2_drop: the tilted fit is taken only when it lowers the chi-square (sum
            of squared reprojection errors over sigma^2) by more than this; 9.21 is the 99 %
            point of chi-square with 2 dof, 0 always takes it.
        loss: robust loss of the level fit, "huber" or "cauchy" (`pose_planar`), or None
            (least squares).
        loss_scale: the robust loss's threshold, in sigmas.
        min_separation_px: spots closer than this in the image count as coincident, pixels.
        max_iterations: Gauss-Newton iterations before giving up.
    """

    estimate_tilt: bool = False
    tilt_sigma_rad: float | None = None
    tilt_min_chi2_drop: float = 9.21
    loss: RobustLoss | None = None
    loss_scale: float = 2.0
    min_separation_px: float = 2.0
    max_iterations: int = 20
