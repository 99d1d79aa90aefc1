"""How far a spot's measured pixel may lie from where the map and the pose put it.

Three independent parts, added in quadrature, per landmark:

- the centroid's own noise (`centroid_sigma_px`);
- the survey: a landmark `survey_sigma_m` off in the map moves its spot by that times the
  image scale (pixels per metre of ceiling);
- the calibration: nobody has an exact one. With the calibration's own uncertainty (focal
  length `focal_rel`, principal point `principal_px`, each distortion coefficient
  `distortion_rel` of itself), a pixel at radius r from the principal point moves by
  sigma_cal(r): computed once per camera by perturbing each parameter and reprojecting the
  same ray (`calibration_sigma_table`). It grows with the radius, steeply for a strong
  radial-tangential lens: a few pixels at the edge of a wide lens is normal.

The first two are independent from landmark to landmark; the calibration's error is not (it
distorts the whole image alike), so a fix's covariance also carries it as a consider term
(`calibration_consider`, `PixelNoiseModel.calibration_covariance`) that does not shrink with
the number of landmarks. The per-spot sigma here (all three parts) stays the weight of the fit,
the fit's own covariance and the scale of the per-spot outlier and chi-square tests: a residual
still holds the calibration's systematic displacement of its spot (less what the pose
absorbs), and on recordings of an independent generator (`bench/foreign`) a per-spot sigma of
the centroid and survey alone made fixes of two landmarks over-confident (spot shape and blur
that the calibration part covers).

The defaults are a prior. `PixelNoiseModel.observe` adapts one common scale factor online
from the fixes' normalised residuals (chi-square over its degrees of freedom, which is 1 on
average when the model is right), within `adapt_bounds`.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from localizer.calibration_consider import CalibrationConsider
from localizer.camera import CameraModel, normalized_from_pixels, pixels_from_points_camera
from localizer.types import FloatArray


@dataclass(frozen=True)
class PixelNoiseConfig:
    """The pixel-noise model's prior and its adaptation.

    Attributes:
        centroid_sigma_px: a spot centroid's own noise per axis, pixels.
        survey_sigma_m: the map's survey error per axis, metres.
        focal_rel: relative uncertainty of the focal lengths (0.2 %: a realistic one).
        principal_px: uncertainty of the principal point, pixels.
        distortion_rel: relative uncertainty of each distortion coefficient.
        adapt: adapt the scale factor from the fixes' residuals.
        adapt_gain: weight of one fix in that running estimate.
        adapt_bounds: the scale factor stays within these.
        adapt_min_landmarks: fixes from fewer landmarks do not adapt it (too few degrees of
            freedom to tell noise from a pose error).
        consider_reuse_m, consider_reuse_rad: a fix's calibration term
            (`calibration_covariance`) is reused for the same landmarks (turned with the
            heading) until the pose has moved this far, metres / radians.
    """

    centroid_sigma_px: float = 0.5
    survey_sigma_m: float = 0.004
    focal_rel: float = 0.002
    principal_px: float = 0.6
    distortion_rel: float = 0.05
    adapt: bool = True
    adapt_gain: float = 0.02
    adapt_bounds: tuple[float, float] = (0.2, 3.0)
    adapt_min_landmarks: int = 3
    consider_reuse_m: float = 0.05
    consider_reuse_rad: float = 0.1

    def __post_init__(self) -> None:
        for name in (
            "centroid_sigma_px",
            "survey_sigma_m",
            "focal_rel",
            "principal_px",
            "distortion_rel",
            "adapt_gain",
            "consider_reuse_m",
            "consider_reuse_rad",
        ):
            v = getattr(self, name)
            if not math.isfinite(v) or v < 0:
                raise ValueError(f"PixelNoiseConfig: {name} must be >= 0, got {v!r}")
        lo, hi = self.adapt_bounds
        if not 0 < lo <= 1 <= hi:
            raise ValueError(f"PixelNoiseConfig: adapt_bounds need 0 < lo <= 1 <= hi, got {lo, hi}")


def calibration_sigma_table(
    camera: CameraModel, config: PixelNoiseConfig, samples: int = 24
) -> tuple[FloatArray, FloatArray]:
    """sigma_cal at radii from the principal point to the farthest image corner.

    Each parameter is perturbed by its uncertainty in turn; the ray of the pixel at radius r
    (along the diagonals, where the radius is largest) is reprojected through the perturbed
    camera, and the displacements are added in quadrature. Rays that do not invert (past a
    fisheye's field of view) take the last valid value.

    Returns:
        (radii shape (samples,), sigma_cal shape (samples,)), pixels.
    """
    cu, cv = camera.cu, camera.cv
    corners = np.array(
        [
            [0, 0],
            [camera.width - 1, 0],
            [0, camera.height - 1],
            [camera.width - 1, camera.height - 1],
        ],
        float,
    )
    r_max = float(np.max(np.hypot(corners[:, 0] - cu, corners[:, 1] - cv)))
    radii = np.linspace(0.0, r_max, samples)
    dirs = (corners - [cu, cv]) / np.hypot(*(corners - [cu, cv]).T)[:, None]
    px = (np.array([cu, cv]) + radii[:, None, None] * dirs[None]).reshape(-1, 2)
    m = normalized_from_pixels(camera, px)
    rays = np.column_stack([m, np.ones(len(m))])
    good = np.all(np.isfinite(rays), axis=1)
    rays[~good] = (0.0, 0.0, 1.0)
    var = np.full(len(px), float(config.principal_px) ** 2)
    perturbed = [
        dataclasses.replace(
            camera, fu=camera.fu * (1 + config.focal_rel), fv=camera.fv * (1 + config.focal_rel)
        )
    ]
    for i, k in enumerate(camera.distortion):
        if k != 0.0:
            d = camera.distortion.copy()
            d[i] = k * (1 + config.distortion_rel)
            perturbed.append(dataclasses.replace(camera, distortion=d))
    base, _ = pixels_from_points_camera(camera, rays)
    for cam in perturbed:
        moved, _ = pixels_from_points_camera(cam, rays)
        var += np.sum((moved - base) ** 2, axis=1)
    sig = np.sqrt(var).reshape(samples, len(dirs))
    ok = good.reshape(samples, len(dirs))
    out = np.array(
        [float(np.mean(row[k])) if np.any(k) else math.nan for row, k in zip(sig, ok, strict=True)]
    )
    for i in range(1, samples):  # past the invertible area: the last valid value
        if not math.isfinite(out[i]):
            out[i] = out[i - 1]
    return radii, np.nan_to_num(out, nan=config.principal_px)


class PixelNoiseModel:
    """Per-landmark pixel standard deviation (module docstring), adapted online.

    Args:
        camera: the calibrated camera (its uncertainty is `config`'s).
        config: the prior and the adaptation.
        scale_px_per_m: the image scale of the ceiling (for the survey part).

    Attributes:
        factor: the adapted scale factor (1: the prior).
    """

    def __init__(self, camera: CameraModel, config: PixelNoiseConfig, scale_px_per_m: float):
        self.config = config
        self.factor = 1.0
        radii, cal = calibration_sigma_table(camera, config)
        base2 = config.centroid_sigma_px**2 + (config.survey_sigma_m * scale_px_per_m) ** 2
        self._step = float(radii[1] - radii[0]) if len(radii) > 1 else 1.0
        self._table = [math.sqrt(base2 + c * c) for c in cal.tolist()]
        self._survey_px = config.survey_sigma_m * scale_px_per_m
        self._scale = scale_px_per_m
        self._cu, self._cv = camera.cu, camera.cv
        self.consider = CalibrationConsider.for_camera(
            camera,
            focal_rel=config.focal_rel,
            principal_px=config.principal_px,
            distortion_rel=config.distortion_rel,
        )

    def calibration_covariance(
        self,
        pixels: list[list[float]],
        p_world: FloatArray,
        pose: tuple[float, float, float],
        sigma_px: list[float],
    ) -> FloatArray | None:
        """The calibration's consider term A Sigma_cal A^T, shape (3, 3), of a level fit at
        `pose` weighted by `sigma_px` (this model's sigmas); None when degenerate."""
        found = self.consider.covariance(pixels, p_world, pose, sigma_px, self.factor)
        return None if found is None else found[1]

    def calibration_jacobian(self, pixels: list[list[float]]) -> FloatArray:
        """d pixel per standard deviation of each calibration parameter at `pixels`, shape
        (N, 2, P) (`CalibrationConsider.scaled_jacobian`, this model's factor applied)."""
        return self.consider.scaled_jacobian(pixels, self.factor)

    def sigma_px(self, u: float, v: float, survey_m: float | None = None) -> float:
        """The standard deviation of a spot at pixel (u, v), per axis, pixels; with
        `survey_m`, of a landmark whose map position is known to that (metres, 1 sigma)
        instead of `survey_sigma_m`: a landmark surveyed to 1 mm weighs more than a taped one.
        """
        f = math.hypot(u - self._cu, v - self._cv) / self._step
        i = int(f)
        table = self._table
        if i >= len(table) - 1:
            s = table[-1]
        else:
            a = f - i
            s = (1.0 - a) * table[i] + a * table[i + 1]
        if survey_m is not None:
            own = survey_m * self._scale
            s = math.sqrt(max(s * s - self._survey_px**2, 0.0) + own * own)
        return self.factor * s

    def pair_sigma_px(self, sigma_px: float) -> float:
        """The sigma a fix of two landmarks is tested by, for a spot of this model's
        `sigma_px`: the survey's part at its prior even when the factor has fallen below 1.

        A two-landmark fix has one degree of freedom, the distance between its two spots,
        and what moves that is the survey error of that one pair (and the focal scale), the
        same on every frame of it. The factor is learnt from fixes of 3+ landmarks, whose
        residuals say how much of the modelled calibration error a fit of many spots
        absorbs (at the edges of a strong lens, most of it): a factor of 0.2 there made the
        pair's sigma a fifth of its survey's, and a pair surveyed 1 cm apart from the truth
        (two standard deviations at 4 mm per axis) was refused frame after frame while its
        spots sat within a pixel of their predictions."""
        f = self.factor
        if f >= 1.0:
            return sigma_px
        return math.sqrt(sigma_px * sigma_px + (1.0 - f * f) * self._survey_px**2)

    def white_share(self, sigma_px: list[float]) -> float:
        """The share of a fix's variance that is white (the centroids' own noise, new on
        every frame; the survey's and the calibration's parts are the same on every frame
        of the same landmarks), for spots of these sigmas (this model's): the mean over the
        spots of (centroid sigma / sigma)^2, the adapted factor applying to both."""
        if not sigma_px:
            return 1.0
        c = self.factor * self.config.centroid_sigma_px
        return min(1.0, sum((c / s) ** 2 for s in sigma_px) / len(sigma_px))

    def observe(self, chi2: float, n_landmarks: int) -> None:
        """Adapt the factor from a fix's chi-square (sum of squared residuals over this
        model's sigmas) with `n_landmarks` landmarks (2n - 3 degrees of freedom)."""
        cfg = self.config
        if not cfg.adapt or n_landmarks < cfg.adapt_min_landmarks or not math.isfinite(chi2):
            return
        ratio = min(chi2 / (2 * n_landmarks - 3), 25.0)  # one wild fix moves it boundedly
        f2 = self.factor**2 * (1.0 + cfg.adapt_gain * (ratio - 1.0))
        lo, hi = cfg.adapt_bounds
        self.factor = min(max(math.sqrt(max(f2, 0.0)), lo), hi)
