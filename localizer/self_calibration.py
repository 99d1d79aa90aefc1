"""Self-calibration: the principal point, the first distortion terms, the focal scale and the
mounting yaw, estimated from a window of fixes where the data make them observable.

A window of frames, each with its matched spots (pixels), their landmarks (world points) and
the raw odometry pose at the frame, is adjusted jointly (a small bundle adjustment): the
unknowns are the corrections

    c = (delta cu px, delta cv px, k1 relative, k2 relative, focal relative, mounting yaw rad)

and every frame's body pose (x, y, theta); the residuals are the reprojection errors over the
pixel sigma (Huber-weighted), the odometry's relative motion between consecutive frames over
its sigma, and a prior on c (the calibration's own uncertainty, or online the estimate of the
windows before). Gauss-Newton on the dense normal equations (6 + 3M unknowns): one OpenCV
projection of every point per iteration gives the pixels and, from its Jacobian, their
derivatives in the lens parameters and the camera-frame point; the pose derivatives follow by
the chain rule.

What makes each correction observable (and so when it converges, see `lens_converged`):
- the radial terms and the focal scale: landmarks over a range of image radii in the same
  frame (many landmarks in view; a 3-landmark cluster at one radius leaves them to the prior);
- the principal point: a shift of it moves every spot almost alike, like a translation of
  the body; what tells them apart is the distortion pattern around the true centre (a strong
  wide lens shows it in one view) and turning in place (the translation it mimics turns with
  the heading while odometry says the body stayed);
- the mounting yaw: a yawed camera turns every fix's heading alike, invisible in one frame;
  driving straight, odometry says which way the body moved, and the fixes' track shows the
  yaw between the two (as far as odometry's own heading drift lets it).

Convergence: the lens terms are strongly correlated (k1, k2 and the focal scale trade off),
so they are judged together by what they do to the image: the lens block has converged when
the posterior's pixel standard deviation, averaged over the window's spots, is below
`converge_fraction` of the prior's, and each coordinate of the principal point's own standard
deviation is below that fraction of its prior's (a centre shift biases every fix alike). The
yaw has converged when its posterior standard deviation is below that fraction of its
prior's. Only converged parts are applied.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Generator
from dataclasses import dataclass
from typing import TypeVar

import numpy as np
import numpy.typing as npt

from localizer.calibrated_camera import corrected_camera, project_with_jacobians
from localizer.camera import CameraModel
from localizer.geometry import wrap_angle
from localizer.types import FloatArray, Pose

Frame = tuple[FloatArray, FloatArray, Pose, Pose]
T = TypeVar("T")
NAMES = ("cu_px", "cv_px", "k1_rel", "k2_rel", "focal_rel", "yaw_rad")
LENS = slice(0, 5)  # the lens block of c
YAW = 5


@dataclass(frozen=True)
class SelfCalibrationConfig:
    """Tuning of `SelfCalibration` and of its online use (`online_calibration`).

    Attributes:
        enabled: the localizer runs the online self-calibration (`LocalizerConfig`).
        window_frames: frames adjusted together.
        min_landmarks: frames with fewer matched landmarks are not kept.
        keep_every_s: online, a fix is kept at most this often, seconds (views far enough
            apart that odometry between them says something; a window spans
            `window_frames` x this).
        max_keep_every_s: online, each candidate the gate turns down (the estimate has
            stopped improving on the calibration in use) doubles that interval, up to this:
            a settled calibration costs little.
        pixel_sigma_px: reprojection noise, pixels.
        huber_sigmas: reprojection residuals beyond this many sigmas are down-weighted
            (Huber), so a stray pair costs little.
        iterations: Gauss-Newton iterations at most.
        odometry_sigma_m: noise of odometry's relative translation between two kept
            frames, metres (plus `odometry_sigma_frac` of the distance forward and
            `odometry_lateral_frac` of it sideways).
        odometry_sigma_frac: relative part of it, forward (wheel scale).
        odometry_lateral_frac: relative part of it, sideways.
        odometry_sigma_rad: noise of its relative rotation, radians, plus
            `odometry_turn_frac` of the turn.
        odometry_turn_frac: relative part of the rotation's noise.
        odometry_curvature_sigma_rad_per_m: prior of odometry's systematic heading drift
            per metre driven (unequal wheel radii), estimated with the window, rad/m:
            without it that drift would pass for a mounting yaw.
        odometry_turn_scale_sigma: prior of odometry's systematic turn scale error (a wrong
            wheel base), estimated with the window.
        prior_sigma: prior standard deviations of c (`NAMES` order: px, px, relative,
            relative, relative, rad): the handed-over calibration's own uncertainty.
        converge_fraction: a part has converged when its posterior standard deviation (the
            lens block: in pixels) is below this fraction of its prior's.
        max_prior_sigmas: a converged correction farther than this many prior standard
            deviations from the handed-over calibration is implausible (a floor tilt or a
            wrong map mimics it) and not applied.
        min_improvement: online, a candidate calibration is applied only when it lowers the
            reprojection chi-square of the next window's fixes (data it was not estimated
            from) by at least this fraction against the calibration in use.
        max_odometry_chi2: online, a window whose odometry residuals' chi-square per
            residual exceeds this (fixes and odometry disagree: a kidnap, wheel slip) is
            dropped: neither its estimate nor its frames are used.
    """

    enabled: bool = True
    window_frames: int = 10
    min_landmarks: int = 3
    keep_every_s: float = 0.1
    max_keep_every_s: float = 2.0
    pixel_sigma_px: float = 0.5
    huber_sigmas: float = 3.0
    iterations: int = 8
    odometry_sigma_m: float = 0.0005
    odometry_sigma_frac: float = 0.01
    odometry_lateral_frac: float = 0.002
    odometry_sigma_rad: float = 0.002
    odometry_turn_frac: float = 0.005
    odometry_curvature_sigma_rad_per_m: float = 0.05
    odometry_turn_scale_sigma: float = 0.05
    prior_sigma: tuple[float, float, float, float, float, float] = (1.0, 1.0, 0.1, 0.1, 0.004, 0.02)
    converge_fraction: float = 0.25
    max_prior_sigmas: float = 3.0
    min_improvement: float = 0.02
    max_odometry_chi2: float = 25.0

    def __post_init__(self) -> None:
        if self.window_frames < 2 or self.min_landmarks < 2:
            raise ValueError(
                "SelfCalibrationConfig: window_frames and min_landmarks must be >= 2, got "
                f"{self.window_frames}, {self.min_landmarks}"
            )
        if len(self.prior_sigma) != len(NAMES) or not all(v > 0 for v in self.prior_sigma):
            raise ValueError(
                f"SelfCalibrationConfig: prior_sigma needs {len(NAMES)} positive values "
                f"({', '.join(NAMES)}), got {self.prior_sigma}"
            )


@dataclass(frozen=True, eq=False)
class CalibrationEstimate:
    """The corrections (`NAMES` order), their covariance, and which parts have converged.

    Attributes:
        correction: c, shape (6,).
        covariance: its posterior covariance, shape (6, 6).
        lens_converged: the lens block (cu, cv, k1, k2, focal) has converged.
        yaw_converged: the mounting yaw has converged.
        pixel_sigma_ratio: the lens block's posterior pixel sigma over its prior's.
        odometry_chi2: the odometry residuals' chi-square per residual at the solution (about
            1 or less when fixes and odometry agree; far more across a kidnap or a slip).
        frames: frames adjusted.
    """

    correction: FloatArray
    covariance: FloatArray
    lens_converged: bool
    yaw_converged: bool
    pixel_sigma_ratio: float
    frames: int
    odometry_chi2: float = 0.0

    @property
    def sigma(self) -> FloatArray:
        return np.sqrt(np.maximum(np.diag(self.covariance), 0.0))

    @property
    def converged(self) -> tuple[bool, ...]:
        """Per correction (`NAMES` order)."""
        return (self.lens_converged,) * 5 + (self.yaw_converged,)


def _relative(a: Pose, b: Pose) -> tuple[float, float, float]:
    """b in a's frame: (forward, left, turn)."""
    c, s = math.cos(a[2]), math.sin(a[2])
    dx, dy = b[0] - a[0], b[1] - a[1]
    return c * dx + s * dy, -s * dx + c * dy, float(wrap_angle(b[2] - a[2]))


def run_steps(steps: Generator[None, None, T]) -> T:
    """Run a step-wise computation (a generator yielding between its steps) to its end and
    return its result."""
    while True:
        try:
            next(steps)
        except StopIteration as done:
            return done.value  # type: ignore[no-any-return]


class SelfCalibration:
    """Collects fixes and estimates the corrections (see the module docstring).

    Args:
        camera: the calibration handed over.
        config: tuning.
    """

    def __init__(self, camera: CameraModel, config: SelfCalibrationConfig | None = None):
        self.camera = camera
        self.config = config or SelfCalibrationConfig()
        self._frames: deque[Frame] = deque(maxlen=self.config.window_frames)
        self._floors: deque[tuple[float, float, float]] = deque(maxlen=self.config.window_frames)
        self.estimate: CalibrationEstimate | None = None

    def __len__(self) -> int:
        return len(self._frames)

    @property
    def frames(self) -> list[Frame]:
        """The collected frames: (pixels (N, 2), landmarks (N, 3), fixed pose, odometry pose)."""
        return list(self._frames)

    @property
    def floors(self) -> FloatArray:
        """Each collected frame's floor (roll, pitch, dz), shape (M, 3)."""
        return np.array(self._floors, dtype=np.float64).reshape(-1, 3)

    def add(
        self,
        pixels: npt.ArrayLike,
        p_world: npt.ArrayLike,
        pose: Pose,
        odometry: Pose,
        floor: npt.ArrayLike | None = None,
    ) -> None:
        """One fix: the spots (N, 2), their landmarks (N, 3), the fixed pose, the raw
        odometry pose at that frame, and the floor the fix stood on ((roll, pitch, dz),
        `floor_plane`; None: level)."""
        px = np.asarray(pixels, dtype=np.float64).reshape(-1, 2)
        if len(px) < self.config.min_landmarks:
            return
        P = np.asarray(p_world, dtype=np.float64).reshape(-1, 3)
        a, b = tuple(map(float, pose)), tuple(map(float, odometry))
        self._frames.append((px, P, (a[0], a[1], a[2]), (b[0], b[1], b[2])))
        fl = (0.0, 0.0, 0.0) if floor is None else tuple(map(float, np.ravel(floor)[:3]))
        self._floors.append((fl[0], fl[1], fl[2]))

    def clear(self) -> None:
        """Forget the collected frames (the last estimate stays)."""
        self._frames.clear()
        self._floors.clear()

    def solve(
        self, prior_mean: npt.ArrayLike | None = None, prior_covariance: npt.ArrayLike | None = None
    ) -> CalibrationEstimate | None:
        """Adjust the window; None with fewer than two frames or when it fails.

        Args:
            prior_mean: the corrections' prior mean, shape (6,) (default zeros: the
                calibration handed over); online, the estimate of the windows before (a
                recursive estimate over disjoint windows).
            prior_covariance: its covariance, shape (6, 6) (default diag(prior_sigma^2)).
        """
        return run_steps(self.solve_steps(prior_mean, prior_covariance))

    def solve_steps(
        self, prior_mean: npt.ArrayLike | None = None, prior_covariance: npt.ArrayLike | None = None
    ) -> Generator[None, None, CalibrationEstimate | None]:
        """`solve` a part of a Gauss-Newton iteration at a time: each `next()` does the
        spots' or the odometry's part of one (the online self-calibration spreads a window's
        adjustment over the frames that follow it, so that no frame pays for all of it); the
        estimate is the generator's return value. It adjusts the frames collected now (a
        later `clear` or `add` does not change them)."""
        return self._solve_steps(list(self._frames), self.floors, prior_mean, prior_covariance)

    def _solve_steps(
        self,
        frames: list[Frame],
        floors: FloatArray,
        prior_mean: npt.ArrayLike | None,
        prior_covariance: npt.ArrayLike | None,
    ) -> Generator[None, None, CalibrationEstimate | None]:
        M = len(frames)
        if M < 2:
            return None
        cfg = self.config
        prior = np.asarray(cfg.prior_sigma, dtype=np.float64)
        mu = np.zeros(6) if prior_mean is None else np.asarray(prior_mean, dtype=np.float64)
        C0 = np.diag(prior**2) if prior_covariance is None else np.asarray(prior_covariance, float)
        try:
            W0 = np.linalg.inv(C0)
        except np.linalg.LinAlgError:
            return None
        px = np.concatenate([f[0] for f in frames])
        P = np.concatenate([f[1] for f in frames])
        frame = np.concatenate([np.full(len(f[0]), i) for i, f in enumerate(frames)])
        odo = np.array([_relative(frames[i][3], frames[i + 1][3]) for i in range(M - 1)])
        d = np.hypot(odo[:, 0], odo[:, 1])
        s_fwd = cfg.odometry_sigma_m + cfg.odometry_sigma_frac * d
        s_lat = cfg.odometry_sigma_m + cfg.odometry_lateral_frac * d
        s_rad = cfg.odometry_sigma_rad + cfg.odometry_turn_frac * np.abs(odo[:, 2])
        w_odo = 1.0 / np.column_stack([s_fwd, s_lat, s_rad]) ** 2
        # unknowns: c (6), odometry's curvature bias kappa (rad/m) and turn scale error
        # beta (systematic: unequal wheel radii, a wrong wheel base), the poses (3 M)
        n_c = 8
        mu8 = np.concatenate([mu, [0.0, 0.0]])
        W8 = np.zeros((n_c, n_c))
        W8[:6, :6] = W0
        W8[6, 6] = 1.0 / cfg.odometry_curvature_sigma_rad_per_m**2
        W8[7, 7] = 1.0 / cfg.odometry_turn_scale_sigma**2
        c = mu8.copy()
        poses = np.array([f[2] for f in frames], dtype=np.float64)
        n_u = n_c + 3 * M
        H = np.zeros((n_u, n_u))
        d_c = np.zeros((0, 2, 6))
        starts = np.searchsorted(frame, np.arange(M))  # each frame's first spot (sorted)
        ar, pair = np.arange(M), np.arange(M - 1)
        Hpp = H[n_c:, n_c:].reshape(M, 3, M, 3)  # views: the pose blocks, and their
        Hcp = H[:6, n_c:].reshape(6, M, 3)  # couplings with c and with (kappa, beta)
        Hpc = H[n_c:, :6].reshape(M, 3, 6)
        Hkp = H[6:8, n_c:].reshape(2, M, 3)
        Hpk = H[n_c:, 6:8].reshape(M, 3, 2)
        yield
        for _ in range(cfg.iterations):
            pred, d_c, d_pose = project_with_jacobians(self.camera, c[:6], poses, P, frame, floors)
            r = pred - px  # (N, 2), pixels
            e = np.hypot(r[:, 0], r[:, 1]) / cfg.pixel_sigma_px
            k = cfg.huber_sigmas
            w = np.where(e <= k, 1.0, k / np.maximum(e, 1e-12)) / cfg.pixel_sigma_px**2
            H[:] = 0.0
            g = np.zeros(n_u)
            H[:n_c, :n_c] = W8
            g[:n_c] = W8 @ (c - mu8)
            wd_c = d_c * w[:, None, None]  # W J, the spots' weights (N, 2, 6)
            wd_pose = d_pose * w[:, None, None]
            H[:6, :6] += np.tensordot(wd_c, d_c, axes=([0, 1], [0, 1]))
            g[:6] += np.tensordot(wd_c, r, axes=([0, 1], [0, 1]))
            # each frame's spots: its pose block and its coupling with c (sums per frame)
            cross = np.add.reduceat(wd_c.transpose(0, 2, 1) @ d_pose, starts)  # (M, 6, 3)
            Hcp[:] = cross.transpose(1, 0, 2)
            Hpc[:] = cross.transpose(0, 2, 1)
            Hpp[ar, :, ar, :] = np.add.reduceat(wd_pose.transpose(0, 2, 1) @ d_pose, starts)
            g[n_c:] = np.add.reduceat(np.sum(wd_pose * r[:, :, None], axis=1), starts).ravel()
            yield  # (the spots' part and the odometry's part of an iteration: a step each)
            # odometry: the relative motion between consecutive frames, as biased odometry
            # reads it: turn (1 + beta) + kappa d, the chord turned left by half the extra
            rel, Ja, Jb = _relative_jacobians_many(poses[:-1], poses[1:])
            extra = c[6] * d + c[7] * rel[:, 2]
            ro = (
                np.column_stack([rel[:, 0], rel[:, 1] + 0.5 * rel[:, 0] * extra, rel[:, 2] + extra])
                - odo
            )
            ro[:, 2] = wrap_angle(ro[:, 2])
            Jk = np.zeros((M - 1, 3, 2))  # d ro / d (kappa, beta)
            Jk[:, 1, 0], Jk[:, 1, 1] = 0.5 * rel[:, 0] * d, 0.5 * rel[:, 0] * rel[:, 2]
            Jk[:, 2, 0], Jk[:, 2, 1] = d, rel[:, 2]
            WJa, WJb, WJk = (w_odo[:, :, None] * J for J in (Ja, Jb, Jk))  # Wd J
            Wro = w_odo * ro
            JaT, JbT = Ja.transpose(0, 2, 1), Jb.transpose(0, 2, 1)
            Hpp[pair, :, pair, :] += JaT @ WJa
            Hpp[pair + 1, :, pair + 1, :] += JbT @ WJb
            ab = JaT @ WJb
            Hpp[pair, :, pair + 1, :] += ab
            Hpp[pair + 1, :, pair, :] += ab.transpose(0, 2, 1)
            ak, bk = JaT @ WJk, JbT @ WJk  # (M-1, 3, 2)
            Hpk[pair] += ak
            Hpk[pair + 1] += bk
            Hkp[:, pair, :] += ak.transpose(2, 0, 1)
            Hkp[:, pair + 1, :] += bk.transpose(2, 0, 1)
            H[6:8, 6:8] += np.tensordot(Jk, WJk, axes=([0, 1], [0, 1]))
            gp = g[n_c:].reshape(M, 3)
            gp[pair] += np.sum(Ja * Wro[:, :, None], axis=1)
            gp[pair + 1] += np.sum(Jb * Wro[:, :, None], axis=1)
            g[6:8] += np.tensordot(Jk, Wro, axes=([0, 1], [0, 1]))
            try:
                step = -np.linalg.solve(H, g)
            except np.linalg.LinAlgError:
                return None
            if not np.all(np.isfinite(step)):
                return None
            c = c + step[:n_c]
            poses = poses + step[n_c:].reshape(M, 3)
            yield
            if np.max(np.abs(step[:6]) / prior) < 1e-4:
                break
        try:
            inv = np.linalg.inv(H)[:6, :6]
        except np.linalg.LinAlgError:
            return None
        cov = np.asarray(0.5 * (inv + inv.T), dtype=np.float64)
        ratio = _pixel_sigma_ratio(d_c, cov, np.diag(prior**2))
        frac = cfg.converge_fraction
        sig = np.sqrt(np.maximum(np.diag(cov), 0.0))
        # the block by its pixels, and the centre on its own: a centre shift biases every fix
        # alike, so a poorly known one must not ride along with well-known radial terms
        lens_ok = ratio < frac and bool(np.all(sig[:2] < frac * prior[:2]))
        yaw_ok = bool(sig[YAW] < frac * prior[YAW])
        rel, _, _ = _relative_jacobians_many(poses[:-1], poses[1:])
        extra = c[6] * d + c[7] * rel[:, 2]
        ro = (
            np.column_stack([rel[:, 0], rel[:, 1] + 0.5 * rel[:, 0] * extra, rel[:, 2] + extra])
            - odo
        )
        ro[:, 2] = wrap_angle(ro[:, 2])
        odo_chi2 = float(np.sum(w_odo * ro * ro)) / max(3 * (M - 1), 1)
        self.estimate = CalibrationEstimate(
            c[:6].copy(), cov, lens_ok, yaw_ok, ratio, M, odometry_chi2=odo_chi2
        )
        return self.estimate

    def apply_to(self, camera: CameraModel) -> CameraModel:
        """`camera` with the converged parts of the last `solve` applied."""
        est = self.estimate
        if est is None:
            return camera
        c = np.where(np.array(est.converged), est.correction, 0.0)
        return corrected_camera(camera, c)


def _relative_jacobians_many(
    a: FloatArray, b: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """`_relative(a, b)` for poses a, b of shape (K, 3) and its Jacobians in a and in b:
    shapes (K, 3), (K, 3, 3), (K, 3, 3)."""
    c, s = np.cos(a[:, 2]), np.sin(a[:, 2])
    dx, dy = b[:, 0] - a[:, 0], b[:, 1] - a[:, 1]
    rel = np.column_stack([c * dx + s * dy, -s * dx + c * dy, wrap_angle(b[:, 2] - a[:, 2])])
    Ja = np.zeros((len(a), 3, 3))
    Ja[:, 0, 0], Ja[:, 0, 1], Ja[:, 0, 2] = -c, -s, -s * dx + c * dy
    Ja[:, 1, 0], Ja[:, 1, 1], Ja[:, 1, 2] = s, -c, -c * dx - s * dy
    Ja[:, 2, 2] = -1.0
    Jb = np.zeros((len(a), 3, 3))
    Jb[:, 0, 0], Jb[:, 0, 1], Jb[:, 1, 0], Jb[:, 1, 1], Jb[:, 2, 2] = c, s, -s, c, 1.0
    return rel, Ja, Jb


def _pixel_sigma_ratio(d_c: FloatArray, cov: FloatArray, prior_cov: FloatArray) -> float:
    """The lens block's pixel standard deviation over the spots (d_c: d pixel / d c, shape
    (N, 2, 6)), posterior over prior (RMS over spots and axes)."""
    if len(d_c) == 0:
        return math.inf
    J = d_c[:, :, LENS].reshape(-1, 5)
    post = float(np.mean(np.einsum("ij,jk,ik->i", J, cov[LENS, LENS], J)))
    pri = float(np.mean(np.einsum("ij,jk,ik->i", J, prior_cov[LENS, LENS], J)))
    return math.sqrt(max(post, 0.0) / pri) if pri > 0 else math.inf
