"""A fix from the tracked landmarks, checked and fused (Sec. IV-A; the fusion of Sec. IV-B).

Given (map row, spot pixel) pairs, `solve_pose` finds the body's pose on the floor carried
from fix to fix (`floor_plane`: its tilt and height re-estimated with 3+ landmarks where the
spots demand it); a robust loss and the outlier rule (a residual beyond `outlier_sigma` of
its spot's own pixel sigma) leave bad pairs out, one pair at a time; a spot at the image
edge whose landmark the fixed pose puts outside the image is left out. The fix's covariance
takes the calibration's consider term (`calibration_consider`), and a fix passing its
chi-square per degree of freedom and the normalised innovation against the filter is fused
by `PoseFilter.update_fix`.

`LandmarkTracker` (which finds the pairs) builds on `FixFusion`; this is part of the
tracking hot path, so it works on small Python lists, not numpy arrays.
"""

from __future__ import annotations

import math

import numpy as np

from localizer.camera import CameraModel
from localizer.config import LocalizerConfig
from localizer.floor_plane import FloorPlane, fix_on_floor
from localizer.geometry import wrap_angle
from localizer.handoff import predict_landmarks
from localizer.landmark_map import LandmarkMap
from localizer.noise_model import PixelNoiseModel
from localizer.pose import PoseFix, solve_pose
from localizer.pose_config import PoseSolveConfig
from localizer.pose_filter import PoseFilter
from localizer.types import FloatArray, Pose

# a fused (or rejected) fix: its landmarks' map rows, their spot pixels, the fix
FixPairs = tuple[list[int], list[list[float]], PoseFix]


class FixFusion:
    """Solving, checking and fusing fixes for one camera and map (see the module docstring).

    Args:
        camera, config: as the `Localizer`'s.

    Attributes:
        noise: the pixel noise model (`PixelNoiseModel`), carried across maps.
        last_fused: the last fused fix's map rows, spot pixels and fix (self-calibration).
        last_matched: IDs of the landmarks in the last fused tracking fix (the owner empties
            it when it resets the pose another way).
        last_rejected: the last attempt's fix that failed only the innovation gate (map
            rows, spot pixels, fix), None when it had none (`adopt_rejected`).
        floor: the floor's height and slope carried from fix to fix (`floor_plane`): every
            fix's prior on the body's tilt and height, updated by each fused fix of 3+
            landmarks.
        imu_tilt: the body's (roll, pitch) from an IMU's gravity direction at this frame,
            radians, or None: the solve's floor when none is carried.
    """

    def __init__(self, camera: CameraModel, config: LocalizerConfig) -> None:
        self.camera = camera
        self.config = config
        self.last_fused: FixPairs | None = None
        self.last_rejected: FixPairs | None = None
        self.last_matched: frozenset[int] = frozenset()
        self.floor = FloorPlane.level(config.floor)
        self._floor_shift = (0.0, 0.0, 0.0)  # what the last solve's floor moved its pose by
        self.imu_tilt: tuple[float, float] | None = None

    def _use_map(self, landmark_map: LandmarkMap, scale_px_per_m: float) -> None:
        """Solve against a new map whose ceiling is imaged at `scale_px_per_m` (the noise
        model keeps what the residuals taught so far)."""
        self.map = landmark_map
        self._ids: list[int] = landmark_map.ids.tolist()
        self._positions: list[list[float]] = landmark_map.positions.tolist()  # (for `_solve`)
        self.scale_px_per_m = scale_px_per_m
        old: PixelNoiseModel | None = getattr(self, "noise", None)
        self.noise = PixelNoiseModel(self.camera, self.config.noise, scale_px_per_m)
        if old is not None:
            self.noise.factor = old.factor  # what the residuals taught so far
        self._consider_cache: dict[tuple[int, ...], tuple[Pose, FloatArray]] = {}

    def adopt_rejected(self, filt: PoseFilter) -> tuple[int, ...]:
        """Re-seed `filt` at the last step's rejected fix (`fix_run`: a run of them the
        odometry disagreed with): the pose and its covariance are the fix's (the odometry's
        calibration factors stay), the floor takes it as a fused fix. Returns its IDs."""
        if self.last_rejected is None:
            return ()
        _, _, fix = self.last_rejected
        filt.reset(fix.x, fix.y, fix.theta, fix.covariance)
        self._update_floor(fix)
        self.last_fused = self.last_rejected
        self.last_matched = frozenset(fix.landmark_ids)
        self.last_rejected = None
        return fix.landmark_ids

    def _fuse(
        self,
        filt: PoseFilter,
        pairs: list[tuple[int, int]],
        spot_px: list[list[float]],
        pose: tuple[float, float, float],
        need: float = 0.0,
    ) -> tuple[int, ...]:
        """Solve the pose from matched (map row, spot) pairs; fuse it when consistent and
        when at least `need` landmarks are left in it.

        Robust: with 3+ landmarks the solve uses `FusionConfig.robust_loss`; a landmark whose
        residual then exceeds `outlier_sigma` of its own pixel sigma is left out and the rest
        solved again (one bad pair costs that pair, never the fix); after a tilted fit (no
        per-spot residuals) the bad pairs are found on the level robust fit. The fix is then
        gated by its chi-square per degree of freedom and by its NIS against the filter.
        """
        fc = self.config.fusion
        rows = [r for r, _ in pairs]
        px = [spot_px[s] for _, s in pairs]
        sig = self._spot_sigmas(rows, px)
        fix = self._solve(rows, px, sig, pose, robust=len(rows) >= 3)
        if fix is None:
            return ()
        res = fix.residuals_px
        keep = list(range(len(rows)))
        if res:
            keep = [
                i
                for i, (r, si) in enumerate(zip(res, sig, strict=True))
                if r <= fc.outlier_sigma * si
            ]
        elif len(rows) >= 4 and self._chi2_per_dof(fix, sig) > fc.max_chi2_per_dof:
            # A tilted fit (it returns no per-spot residuals) that the chi-square test will
            # refuse may have taken a bad pair in: a tilt moves every spot alike, so it soaks
            # up part of one wrong spot. Find the bad pairs on the level robust fit: those
            # standing out there (beyond `outlier_sigma` and three times the median residual;
            # a real tilt raises all alike), and solve again without them (a tilt, if real,
            # fitted again). A tilted fit that passes is left as it is.
            level = self._solve(rows, px, sig, pose, robust=True, tilt=False)
            lres = level.residuals_px if level is not None else ()
            if lres:
                bar = 3.0 * float(np.median(lres))
                keep = [
                    i
                    for i, (r, si) in enumerate(zip(lres, sig, strict=True))
                    if r <= max(fc.outlier_sigma * si, bar)
                ]
        if len(keep) < len(rows):
            if len(keep) < 2:
                return ()
            rows, px, sig = (
                [rows[i] for i in keep],
                [px[i] for i in keep],
                [sig[i] for i in keep],
            )
            fix = self._solve(rows, px, sig, (fix.x, fix.y, fix.theta), robust=False)
            if fix is None:
                return ()
            res = fix.residuals_px
        # A spot at the image edge paired with a landmark the fixed pose puts outside the
        # image (a neighbour of the one that made it, during a fast turn): leave it out.
        edge = self._off_image(rows, px, (fix.x, fix.y, fix.theta))
        if edge:
            keep = [i for i in range(len(rows)) if i not in edge]
            if len(keep) < 2:
                return ()
            rows, px, sig = [rows[i] for i in keep], [px[i] for i in keep], [sig[i] for i in keep]
            fix = self._solve(rows, px, sig, (fix.x, fix.y, fix.theta), robust=False)
            if fix is None:
                return ()
            res = fix.residuals_px
        # the centroids' share of the solver's covariance is white, the rest (survey,
        # calibration, its consider term) the same on every frame of these landmarks
        white = fix.covariance * self.noise.white_share(sig) if fc.correlated_fix_error else None
        fix = self._with_calibration(fix, rows, px, sig)
        n = len(rows)
        if n < need:
            return ()
        chi2_per_dof = self._chi2_per_dof(fix, sig)
        gate_sig = sig if n > 2 else [self.noise.pair_sigma_px(s) for s in sig]
        if self._chi2_per_dof(fix, gate_sig) > fc.max_chi2_per_dof:
            return ()
        # A fix that moved the floor: the pose the earlier fixes (on the old floor) gave is
        # read on the new one, as when a calibration is corrected (the filter's belief stays).
        moved = self._floor_shift
        if moved != (0.0, 0.0, 0.0):
            filt.shift(*moved)
        if not filt.update_fix(fix, max_nis=fc.nis_gate, white_covariance=white) <= fc.nis_gate:
            if moved != (0.0, 0.0, 0.0):
                filt.shift(-moved[0], -moved[1], -moved[2])
            self.last_rejected = (rows, px, fix)
            return ()
        self.noise.observe(chi2_per_dof * max(2 * n - 3, 1), n)
        self._update_floor(fix)
        self.last_fused = (rows, px, fix)
        self.last_matched = frozenset(fix.landmark_ids)
        return fix.landmark_ids

    def _update_floor(self, fix: PoseFix) -> None:
        """The carried floor takes a fused fix's posterior of tilt and height (3+ landmarks:
        with fewer the fix kept the prior's, which holds nothing new)."""
        if fix.floor is not None and fix.floor_covariance is not None and fix.n_landmarks >= 3:
            self.floor = self.floor.updated(
                (fix.x, fix.y, fix.theta), fix.floor, fix.floor_covariance, fix.floor_sensitivity
            )

    @staticmethod
    def _chi2_per_dof(fix: PoseFix, sig: list[float]) -> float:
        """The fix's chi-square per degree of freedom (2n - 3) over the spots' sigmas (a
        tilted fit, without per-spot residuals: its RMS against the mean sigma)."""
        n = len(sig)
        res = fix.residuals_px
        if res:
            chi2 = sum([(r / si) ** 2 for r, si in zip(res, sig, strict=True)])
        else:
            chi2 = n * (fix.residual_rms_px / (sum(sig) / n)) ** 2
        return chi2 / max(2 * n - 3, 1)

    def _with_calibration(
        self, fix: PoseFix, rows: list[int], px: list[list[float]], sig: list[float]
    ) -> PoseFix:
        """The fix with the calibration's consider term added to its covariance
        (`calibration_consider`): the part of the calibration's error that is common to
        every landmark and does not shrink with their number. It changes smoothly with the
        view and turns with the camera: for the same landmarks it is reused, turned by the
        change of heading, until the pose has moved `PixelNoiseConfig.consider_reuse_m` or
        `consider_reuse_rad`."""
        pose = (fix.x, fix.y, fix.theta)
        cached = self._consider_cache.get(fix.landmark_ids)
        nc = self.config.noise
        turn = 0.0 if cached is None else float(wrap_angle(pose[2] - cached[0][2]))
        if cached is None or (
            math.hypot(pose[0] - cached[0][0], pose[1] - cached[0][1]) > nc.consider_reuse_m
            or abs(turn) > nc.consider_reuse_rad
        ):
            term = self.noise.calibration_covariance(px, self.map.positions[rows], pose, sig)
            if term is None:
                return fix
            cached, turn = (pose, term), 0.0
            self._consider_cache = {fix.landmark_ids: cached}
        return fix.plus_covariance_turned(cached[1], turn)

    def _off_image(
        self, rows: list[int], px: list[list[float]], pose: tuple[float, float, float]
    ) -> set[int]:
        """Indices of the pairs near the image border whose landmark projects outside the
        image, within `border_px` of its edge (a cut spot's centroid is biased, and a small
        pose error puts it outside), or away from its spot, at `pose`."""
        m = self.config.tracking.edge_check_px
        W, H = self.camera.width, self.camera.height
        near = [
            i for i, (u, v) in enumerate(px) if u < m or v < m or u > W - 1 - m or v > H - 1 - m
        ]
        if not near:
            return set()
        zero = ([0.0] * 3, [0.0] * 3, [0.0] * 3)
        cand = np.array([rows[i] for i in near], dtype=np.int64)
        pred = predict_landmarks(
            self.camera,
            pose,
            zero,
            self.map.positions,
            candidates=cand,
            scale_px_per_m=self.scale_px_per_m,
            reach_m=1e9,
        )
        at = dict(zip(pred.row_list, pred.pixel_list, strict=True))
        out = set()
        b = self.config.tracking.border_px
        for i in near:
            p = at.get(rows[i])
            u, v = px[i]
            if (
                p is None
                or not (b <= p[0] <= W - 1 - b and b <= p[1] <= H - 1 - b)
                or math.hypot(p[0] - u, p[1] - v)
                > self.config.fusion.outlier_sigma * (self.noise.sigma_px(u, v))
            ):
                out.add(i)
        return out

    def _spot_sigmas(self, rows: list[int], px: list[list[float]]) -> list[float]:
        """Each matched spot's pixel sigma, with its landmark's own survey sigma where the
        map states one (`LandmarkMap.sigmas`)."""
        return [
            self.noise.sigma_px(u, v, self.map.sigma_at(r))
            for r, (u, v) in zip(rows, px, strict=True)
        ]

    def _solve(
        self,
        rows: list[int],
        px: list[list[float]],
        sig: list[float],
        initial: tuple[float, float, float],
        *,
        robust: bool,
        tilt: bool = True,
    ) -> PoseFix | None:
        """`solve_pose` of the pairs; on the carried floor (`LocalizerConfig.floor`), its
        tilt and height estimated where the spots demand it beyond the pixel noise and the
        calibration's error (the part of it the carried floor does not share, `floor_plane`
        eq. 6; with a wide prior around it, then fused with it and the pose conditioned on
        the fusion, eqs. 4-5), else the tilt by the zero-mean test (`tilt`: allowed)."""
        fc = self.config.fusion
        cfg = self.config.floor
        carried = self.floor.prior(initial, cfg) if cfg.enabled else None
        aware = carried is not None and cfg.calibration_aware and len(rows) >= 3
        sensitivity = self.floor.sensitivity_at(initial, cfg) if aware else None
        self._floor_shift = (0.0, 0.0, 0.0)
        floor_prior = None if carried is None else self.floor.widened(carried, cfg)
        if carried is None and self.imu_tilt is not None:
            # the IMU's gravity says how the body is tilted: solve on that floor
            ic = self.config.imu
            s, h = ic.tilt_sigma_rad, ic.height_sigma_m
            floor_prior = ((*self.imu_tilt, 0.0), np.diag([s * s, s * s, h * h]))
        fix = solve_pose(
            self.camera,
            px,
            [self._positions[r] for r in rows],
            config=PoseSolveConfig(
                estimate_tilt=tilt and fc.tilt_from_landmarks and len(rows) >= 3,
                tilt_sigma_rad=fc.tilt_sigma_rad,
                loss=fc.robust_loss if robust else None,
                loss_scale=fc.robust_scale,
            ),
            initial=initial,
            floor_prior=floor_prior,
            calibration_jacobian=self.noise.calibration_jacobian if aware else None,
            floor_sensitivity=sensitivity,
            pixel_sigma_px=sig,
            landmark_ids=tuple([self._ids[r] for r in rows]),
        )
        if carried is None or fix is None:
            return fix
        fix, self._floor_shift = fix_on_floor(
            fix, carried, self.floor.widened(carried, cfg), cfg.reset_chi2, sensitivity
        )
        return fix
