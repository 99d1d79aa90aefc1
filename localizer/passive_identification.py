"""Identification of passive landmarks (lights that cannot blink) by geometry, over frames.

A site's own ceiling lights, or LEDs whose radio is out, can be identified only by where
they are. `PassiveIdentifier` does it for the localizer while it has no pose (a cold start)
or has one it cannot trust (a start pose, lost):

- every `every_s`, one frame's spots are matched to the map as a constellation
  (`constellation.match_constellation`, around the prior when there is one); a unique match
  is taken at once;
- meanwhile the hypotheses are kept alive over frames (`hypothesis_set.HypothesisSet`,
  seeded by the constellation's triangles, carried by the odometry or the motion model,
  scored on every frame): on a regular grid, an ambiguity that one frame cannot settle
  resolves as the map's edge or an irregularity comes into view;
- the accepted (map row, spot) pairs are solved (`solve_pose`) and verified by the
  reprojection of every pair (`fix_from_pairs`): a fix, or nothing.

`status` keeps the last decision and its reason ("ambiguous: 82 distinct poses ...") for
the owner to show. Tolerances come from each light's own uncertainty: the map's `sigmas`
where it states them, else `PassiveConfig.landmark_sigma_m`.

`passive_settings` widens the detector and the tracking windows to the lights' size in the
image (a panel of 60 cm at 2.5 m is 70 px across where an LED is 3).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence

import numpy as np

from localizer.camera import CameraModel
from localizer.config import LocalizerConfig
from localizer.constellation import (
    ConstellationConfig,
    ConstellationMatch,
    constellation_hypotheses,
    match_constellation,
    scoring_config,
)
from localizer.hypothesis_scoring import FrameView
from localizer.hypothesis_set import HypothesisSet
from localizer.landmark_map import LandmarkMap
from localizer.noise_model import PixelNoiseModel
from localizer.passive_config import PassiveConfig
from localizer.pose import PoseFix, solve_pose
from localizer.pose_config import PoseSolveConfig
from localizer.relocalization import RelocalizationConfig
from localizer.spots import Spots
from localizer.triangles import MapTriangles, map_triangles
from localizer.types import FloatArray

Pose = tuple[float, float, float]
_HUBER = PoseSolveConfig(loss="huber")  # a fix robust to a misplaced light
_NS = 1e-9


def light_radius_px(camera: CameraModel, landmark_map: LandmarkMap) -> float:
    """The largest light's radius in the image at its nearest (straight above the camera),
    pixels (0: all are points)."""
    if landmark_map.sizes is None or not len(landmark_map):
        return 0.0
    height = float(np.min(landmark_map.positions[:, 2])) - float(camera.T_body_camera[2, 3])
    return 0.5 * float(np.max(landmark_map.sizes)) * max(camera.fu, camera.fv) / max(height, 0.3)


def passive_settings(
    config: LocalizerConfig, camera: CameraModel, landmark_map: LandmarkMap
) -> LocalizerConfig:
    """The settings widened for the map's lights where they are larger than LED spots: the
    detector's largest blob (the light straight above, 1.5 x), smallest (0.5 % of it: a
    light's fragment at the edge of the view, or a speck, is no light) and elongation, the
    tracking
    windows' smallest half size (a window must hold the whole blob, or its centroid is cut)
    and the pose's pixel noise floor. Never narrowed; unchanged for a map of points."""
    r = light_radius_px(camera, landmark_map)
    if r <= 2.0 or not config.passive.applies_to(landmark_map):
        return config
    det, trk = config.detection, config.tracking
    area = math.ceil(1.5 * math.pi * r * r) + 1
    return dataclasses.replace(
        config,
        detection=dataclasses.replace(
            det,
            max_area_px=max(det.max_area_px, area),
            min_area_px=max(det.min_area_px, round(0.005 * math.pi * r * r)),
            max_elongation=max(det.max_elongation, config.passive.max_elongation),
            centroid_margin_px=max(det.centroid_margin_px, 3),
            drop_border_blobs=True,
        ),
        tracking=dataclasses.replace(
            trk,
            min_half_size_px=max(trk.min_half_size_px, r + 4.0),
            max_half_size_px=max(trk.max_half_size_px, 2.0 * r + 40.0),
        ),
    )


def landmark_sigma_m(landmark_map: LandmarkMap, config: PassiveConfig) -> float:
    """The lights' typical position sigma: the median the map states, else the setting."""
    if landmark_map.sigmas is not None:
        stated = landmark_map.sigmas[np.isfinite(landmark_map.sigmas)]
        if len(stated):
            return max(float(np.median(stated)), 1e-3)
    return config.landmark_sigma_m


def fix_from_pairs(
    camera: CameraModel,
    landmark_map: LandmarkMap,
    spot_pixels: FloatArray,
    pairs: Sequence[tuple[int, int]],
    pixel_sigmas: Sequence[float],
    initial: Pose,
    *,
    outlier_sigma: float,
) -> PoseFix | None:
    """The pose of identified (map row, spot index) pairs, verified by reprojection: a
    robust least-squares fit, accepted when at least 80 % of the pairs (and 3) reproject
    within `outlier_sigma` of their pixel sigma.

    Args:
        spot_pixels: the frame's spots, shape (S, 2).
        pixel_sigmas: each pair's pixel sigma.
    """
    if len(pairs) < 3:
        return None
    rows = [r for r, _ in pairs]
    px = spot_pixels[[s for _, s in pairs]]
    fix = solve_pose(
        camera,
        px,
        landmark_map.positions[rows],
        initial=initial,
        pixel_sigma_px=list(pixel_sigmas),
        landmark_ids=tuple(int(landmark_map.ids[r]) for r in rows),
        config=_HUBER,
    )
    if fix is None:
        return None
    res = fix.residuals_px or (fix.residual_rms_px,) * len(rows)
    good = sum(1 for e, s in zip(res, pixel_sigmas, strict=True) if e <= outlier_sigma * s)
    return fix if good >= max(3, 0.8 * len(rows)) else None


class PassiveIdentifier:
    """Identification by geometry over frames (see the module docstring).

    Args:
        config: `PassiveConfig`.
        constellation: the matcher's tuning.
        relocalization: the hypothesis scoring's tuning (widened to the lights'
            uncertainty by `constellation.scoring_config`).

    Attributes:
        active: whether the current map is identified by geometry.
        status: the last one-frame decision (None before any).
    """

    def __init__(
        self,
        config: PassiveConfig,
        constellation: ConstellationConfig,
        relocalization: RelocalizationConfig,
    ) -> None:
        self.config = config
        self.constellation = constellation
        self._base = relocalization
        self.active = False
        self.status: ConstellationMatch | None = None
        self._t_matched: int | None = None
        self._prior: tuple[Pose, FloatArray] | None = None
        self._index: MapTriangles | None = None
        self._map: LandmarkMap | None = None
        self._sigma = config.landmark_sigma_m
        self.scoring = relocalization
        self._set = HypothesisSet(relocalization)

    def set_map(self, landmark_map: LandmarkMap) -> None:
        """Use a map (its triangles are indexed on first use)."""
        self._map = landmark_map
        self.active = self.config.applies_to(landmark_map)
        self._sigma = landmark_sigma_m(landmark_map, self.config)
        self.scoring = scoring_config(self._base, self.constellation, self._sigma)
        self._index = None
        self._set = HypothesisSet(self.scoring, seeder=self._seed)
        self.clear()

    def clear(self) -> None:
        """Forget the hypotheses and the last decision (a fix was taken, or a new start)."""
        self._set.clear()
        self._t_matched = None
        self.status = None

    def identify(
        self,
        t_ns: int,
        camera: CameraModel,
        spot_pixels: FloatArray,
        odometry_pose: Pose,
        prior: tuple[Pose, FloatArray] | None,
    ) -> tuple[Pose, list[tuple[int, int]]] | None:
        """One frame: the pose and (map row, spot index) pairs of an accepted
        identification, or None (`status` says why not).

        Args:
            odometry_pose: the raw dead-reckoning pose at the frame (any fixed frame).
            prior: (pose, covariance (3, 3)) where the robot is believed to be; None: a
                cold start (anywhere in the map).
        """
        lm = self._map
        if lm is None or not self.active or len(spot_pixels) < 3:
            if lm is not None and self.active:
                self.status = ConstellationMatch(
                    "too_few_spots",
                    f"{len(spot_pixels)} spot(s) on the ceiling: a constellation needs 3 or more",
                    None,
                    [],
                    np.zeros((0, 3)),
                    -math.inf,
                    -math.inf,
                    0,
                )
            return None
        index = self._triangles(lm)
        self._prior = prior
        pose, cov = prior if prior is not None else self._anywhere(lm)
        found = self._set.update(t_ns, odometry_pose, camera, lm.positions, spot_pixels, pose, cov)
        if found.accepted and found.pose is not None:
            return found.pose, found.pairs
        due = self._t_matched is None or (t_ns - self._t_matched) * _NS >= self.config.every_s
        if not due:
            return None
        self._t_matched = t_ns
        self.status = match_constellation(
            camera,
            lm.positions,
            spot_pixels,
            index,
            self.constellation,
            self.scoring,
            landmark_sigma_m=self._sigma,
            prior=prior,
        )
        if self.status.pose is None or not self.status.pairs:
            return None
        return self.status.pose, self.status.pairs

    def fix(
        self,
        t_ns: int,
        camera: CameraModel,
        spots: Spots,
        noise: PixelNoiseModel,
        odometry_pose: Pose,
        prior: tuple[Pose, FloatArray] | None,
    ) -> PoseFix | None:
        """One frame's fix from passive landmarks identified by geometry (`identify`:
        around `prior`, the filter's pose, a start pose or where it got lost; None:
        anywhere), solved and verified by reprojection (`fix_from_pairs`, each spot's sigma
        from `noise` and the light's map sigma); the hypotheses are forgotten once it fixes."""
        found = self.identify(t_ns, camera, spots.pixels, odometry_pose, prior)
        lm = self._map
        if found is None or lm is None:
            return None
        pose, pairs = found
        px = spots.pixels
        sigma = [noise.sigma_px(float(px[s, 0]), float(px[s, 1]), lm.sigma_at(r)) for r, s in pairs]
        fix = fix_from_pairs(
            camera, lm, px, pairs, sigma, pose, outlier_sigma=self.config.outlier_sigma
        )
        if fix is not None:
            self.clear()
        return fix

    def _triangles(self, lm: LandmarkMap) -> MapTriangles:
        """The map's triangles, indexed once per map."""
        if self._index is None:
            self._index = map_triangles(
                lm.positions[:, :2],
                self.config.view_side_m,
                self.constellation.max_map_triangles,
            )
        return self._index

    def _seed(
        self, view: FrameView, prior: Pose, prior_covariance: FloatArray, c: RelocalizationConfig
    ) -> tuple[FloatArray, FloatArray]:
        """The hypothesis set's seeder: the frame's constellation hypotheses (around the
        prior when there is one)."""
        if self._index is None:
            return np.zeros((0, 3)), np.zeros(0)
        return constellation_hypotheses(
            view,
            self._index,
            self.constellation,
            self._sigma,
            self._prior,
            c.prior_gate_chi2,
        )

    @staticmethod
    def _anywhere(lm: LandmarkMap) -> tuple[Pose, FloatArray]:
        """A prior that holds the whole map, any heading (for the set's bookkeeping)."""
        lo, hi = lm.positions[:, :2].min(axis=0), lm.positions[:, :2].max(axis=0)
        c = 0.5 * (lo + hi)
        span = float(np.max(hi - lo)) + 10.0
        return (float(c[0]), float(c[1]), 0.0), np.diag([span**2, span**2, 100.0])


__all__ = [
    "PassiveIdentifier",
    "fix_from_pairs",
    "landmark_sigma_m",
    "light_radius_px",
    "passive_settings",
]
