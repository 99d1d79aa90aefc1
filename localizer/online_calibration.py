"""Online self-calibration: when the localizer collects fixes, adjusts them, and applies a
corrected calibration (the adjustment itself is `self_calibration.SelfCalibration`).

The stream of fixes is cut into disjoint windows of `window_frames` fixes, one kept at most
every `keep_every_s` and only with `min_landmarks` or more landmarks. Each full window is
adjusted with the estimate of the windows before as its prior (a recursive estimate: the
posterior of one window is the prior of the next), starting from the handed-over calibration
and its own uncertainty. A correction is a *candidate* once

1. it has converged: its posterior standard deviation is below `converge_fraction` of the
   prior's (so it is applied only where the data make it observable: k1 with many
   landmarks over a range of radii, the principal point with a strong lens or turning, the
   mounting yaw only from driving), and
2. it is plausible: within `max_prior_sigmas` prior standard deviations of the calibration
   handed over (a floor tilt or a wrong map mimics a large principal-point shift).

The gate that keeps it from ever making things worse: a candidate is applied only when it
explains the *next* window's fixes, which it was not estimated from, better than the
calibration in use: each of those frames is solved again with either camera and the
reprojection chi-square must fall by `min_improvement` or more. Otherwise the calibration in
use stays (and the candidate is dropped; the next window may propose it again). A window whose
fixes and odometry disagree (odometry chi-square per residual above `max_odometry_chi2`: a
kidnap, wheel slip) is not used at all, and when the localizer loses its track (lost, a reset
of the filter) the frames collected so far are dropped (`break_track`): odometry no longer
links them to the next ones. Each turned-
down candidate doubles the interval between kept fixes (up to `max_keep_every_s`): once the
estimate has settled, the self-calibration costs little.

Pure: arrays and dataclasses in, a camera out; time arrives as an argument.
"""

from __future__ import annotations

from collections.abc import Generator
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from localizer.calibrated_camera import corrected_camera
from localizer.camera import CameraModel
from localizer.pose import solve_pose
from localizer.self_calibration import (
    LENS,
    NAMES,
    YAW,
    CalibrationEstimate,
    SelfCalibration,
    SelfCalibrationConfig,
    run_steps,
)
from localizer.types import FloatArray, Pose

_NS = 1e-9


@dataclass(frozen=True, eq=False)
class CalibrationUpdate:
    """A corrected calibration to use from now on.

    Attributes:
        camera: the handed-over camera with `correction` applied.
        correction: c in `self_calibration.NAMES` order, shape (6,).
        chi2_ratio: the validation window's chi-square with it over with the calibration
            in use before (below 1 - `min_improvement`).
    """

    camera: CameraModel
    correction: FloatArray
    chi2_ratio: float


def reprojection_chi2(
    camera: CameraModel,
    frames: list[tuple[FloatArray, FloatArray, Pose, Pose]],
    pixel_sigma_px: float,
    floors: FloatArray | None = None,
) -> float:
    """Sum over frames of the pose fit's chi-square (squared reprojection errors over the
    pixel variance), each frame solved again with `camera` from its pose, on its floor
    (`floors` (M, 3) of (roll, pitch, dz); None: level); inf when one frame does not
    solve."""
    return run_steps(reprojection_chi2_steps(camera, frames, pixel_sigma_px, floors))


def reprojection_chi2_steps(
    camera: CameraModel,
    frames: list[tuple[FloatArray, FloatArray, Pose, Pose]],
    pixel_sigma_px: float,
    floors: FloatArray | None = None,
) -> Generator[None, None, float]:
    """`reprojection_chi2` two frames at a time (a generator yielding after every second
    frame's fit; the sum is its return value)."""
    total = 0.0
    for k, (px, P, pose, _) in enumerate(frames):
        if k and k % 2 == 0:
            yield
        on = None
        if floors is not None:
            r, p, dz = (float(v) for v in floors[k])
            on = ((r, p, dz), np.eye(3) * 1e-12)
        fix = solve_pose(camera, px, P, initial=pose, pixel_sigma_px=pixel_sigma_px, floor_prior=on)
        if fix is None:
            return float("inf")
        total += fix.n_landmarks * (fix.residual_rms_px / pixel_sigma_px) ** 2
    return total


class OnlineCalibration:
    """The online self-calibration's state (module docstring).

    Args:
        camera: the calibration handed over (corrections are relative to it).
        config: tuning.

    Attributes:
        estimate: the recursive estimate after the last window (None before the first).
        applied: the correction in use, shape (6,) (zeros: the handed-over calibration).
        windows: windows adjusted so far.
        rejected: candidates the validation gate turned down.
        dropped: windows whose fixes and odometry disagreed (not used).
    """

    def __init__(self, camera: CameraModel, config: SelfCalibrationConfig) -> None:
        self.camera = camera
        self.config = config
        self._window = SelfCalibration(camera, config)
        prior = np.asarray(config.prior_sigma, dtype=np.float64)
        self._mean = np.zeros(len(NAMES))
        self._cov = np.diag(prior**2)
        self.estimate: CalibrationEstimate | None = None
        self.applied = np.zeros(len(NAMES))
        self._candidate: FloatArray | None = None
        self._t_kept: int | None = None
        self._job: Generator[None, None, CalibrationUpdate | None] | None = None
        self._ready: CalibrationUpdate | None = None
        self.windows = 0
        self.rejected = 0
        self.dropped = 0

    @property
    def camera_in_use(self) -> CameraModel:
        """The handed-over camera with the applied correction."""
        return corrected_camera(self.camera, self.applied) if self.applied.any() else self.camera

    def wants(self, t_ns: int, n_landmarks: int) -> bool:
        """Whether a fix of `n_landmarks` at `t_ns` would be kept (a cheap test first)."""
        if n_landmarks < self.config.min_landmarks:
            return False
        every = min(self.config.keep_every_s * 2.0**self.rejected, self.config.max_keep_every_s)
        return self._t_kept is None or (t_ns - self._t_kept) * _NS >= every

    def observe(
        self,
        t_ns: int,
        pixels: npt.ArrayLike,
        p_world: npt.ArrayLike,
        pose: Pose,
        odometry: Pose,
        floor: npt.ArrayLike | None = None,
    ) -> bool:
        """One fused fix: its spots (N, 2), their landmarks (N, 3), the fixed pose, the raw
        odometry pose at the frame and the floor it stood on ((roll, pitch, dz); None:
        level). Returns whether it completed a window: then the window's validation and
        adjustment begin, carried on by `step` over the frames that follow (a window still
        in work when the next one completes is finished at once); `take_update` hands over
        the calibration to use once they are done."""
        px = np.asarray(pixels, dtype=np.float64).reshape(-1, 2)
        if not self.wants(t_ns, len(px)):
            return False
        self._t_kept = t_ns
        self._window.add(px, p_world, pose, odometry, floor)
        if len(self._window) < self.config.window_frames:
            return False
        self._finish()
        frames, floors = self._window.frames, self._window.floors
        self._job = self._close_window(
            frames, floors, self._window.solve_steps(self._mean, self._cov)
        )
        self._window.clear()
        return True

    def step(self) -> None:
        """Carry a completed window's validation and adjustment on by one step (two frames'
        fits, or a part of a Gauss-Newton iteration); nothing when none is in work."""
        if self._job is None:
            return
        try:
            next(self._job)
        except StopIteration as done:
            self._job = None
            self._ready = done.value or self._ready

    def take_update(self) -> CalibrationUpdate | None:
        """The calibration to use from now on, once, when a window's work ended in one."""
        update, self._ready = self._ready, None
        return update

    @property
    def working(self) -> bool:
        """A completed window's validation and adjustment are still in work."""
        return self._job is not None

    def _finish(self) -> None:
        """Run the window in work to its end."""
        if self._job is not None:
            job, self._job = self._job, None
            self._ready = run_steps(job) or self._ready

    def _close_window(
        self,
        frames: list[tuple[FloatArray, FloatArray, Pose, Pose]],
        floors: FloatArray,
        solving: Generator[None, None, CalibrationEstimate | None],
    ) -> Generator[None, None, CalibrationUpdate | None]:
        """A completed window: the candidate validated on its frames (which it was not
        estimated from), then the window adjusted (the recursive estimate and the next
        candidate); returns the calibration to use, or None."""
        update = yield from self._validate(frames, floors)
        yield
        est = yield from solving
        self.windows += 1
        if est is not None and est.odometry_chi2 > self.config.max_odometry_chi2:
            self.dropped += 1  # fixes and odometry disagree (a kidnap, a slip): not used
        elif est is not None and np.all(np.isfinite(est.covariance)):
            self.estimate, self._mean, self._cov = est, est.correction, est.covariance
            self._candidate = self._propose(est)
        return update

    def break_track(self) -> None:
        """The track of fixes is broken (lost, a kidnap, a reset): odometry no longer links
        the frames collected so far to the next ones, so they are dropped (the estimate and
        the calibration in use stay; a completed window still in work is finished first),
        and so is a candidate not yet validated."""
        self._finish()
        self._window.clear()
        self._candidate = None
        self._t_kept = None

    def _propose(self, est: CalibrationEstimate) -> FloatArray | None:
        """The converged, plausible part of the estimate, if it differs from the applied."""
        prior = np.asarray(self.config.prior_sigma, dtype=np.float64)
        plausible = np.abs(est.correction) <= self.config.max_prior_sigmas * prior
        c = self.applied.copy()
        if est.lens_converged and np.all(plausible[LENS]):
            c[LENS] = est.correction[LENS]
        if est.yaw_converged and plausible[YAW]:
            c[YAW] = est.correction[YAW]
        if np.all(np.abs(c - self.applied) < 0.5 * est.sigma):
            return None  # within its own uncertainty of what is in use
        return c

    def _validate(
        self, frames: list[tuple[FloatArray, FloatArray, Pose, Pose]], floors: FloatArray
    ) -> Generator[None, None, CalibrationUpdate | None]:
        """Apply the candidate when it explains these (new) frames better (module docstring);
        step-wise, a frame's fit a step."""
        c, self._candidate = self._candidate, None
        if c is None:
            return None
        sigma = self.config.pixel_sigma_px
        now = yield from reprojection_chi2_steps(self.camera_in_use, frames, sigma, floors)
        yield
        cam = corrected_camera(self.camera, c)
        new = yield from reprojection_chi2_steps(cam, frames, sigma, floors)
        ratio = new / now if now > 0 else float("inf")
        if not ratio <= 1.0 - self.config.min_improvement:
            self.rejected += 1
            return None
        self.applied = c
        return CalibrationUpdate(cam, c.copy(), ratio)
