"""OpenCV's lens fit, started from a focal estimate and kept clear of degenerate views.

`cv2.fisheye.calibrate` starts, without a guess, from f = max(W, H) / pi. On a wide lens whose
board corners reach far out this puts corners beyond 90 deg off the axis, their undistortion
fails and `InitExtrinsics` asserts (`fabs(norm_u1) > 0`), or the fit ends in a wrong minimum
tens of pixels off. The same photos calibrate when the fit starts near the true focal
length. `focal_estimate` finds one from the views alone: for each candidate f (a geometric
grid), the corners are undistorted by the equidistant model with that f and no distortion
and each view's homography is fitted; the true f makes the board's lines straight again, so
the fit is best there (a 1-D search; the principal point is taken at the image centre).

`fit_lens` then runs OpenCV with `CALIB_USE_INTRINSIC_GUESS` from that estimate; when OpenCV
still fails (a view whose extrinsics it cannot start, e.g. nearly fronto-parallel boards
with another degenerate view), views are dropped one at a time, each the one whose removal
lets the fit succeed with the least error, and the reason is kept for the report.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np

from calibration.board import BoardCorners
from localizer.types import FloatArray

_FISHEYE_CRITERIA = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 200, 1e-12)
FOCAL_GRID = np.geomspace(0.1, 2.0, 48)
"""Candidate focal lengths of `focal_estimate`, as multiples of the image width."""
MAX_FIT_RMS_PX = 5.0
"""A fit whose RMS error exceeds this is taken as failed (a wrong minimum), not as a result."""


@dataclass(frozen=True, eq=False)
class LensFit:
    """OpenCV's result on the views kept.

    Attributes:
        K: camera matrix, shape (3, 3).
        dist: distortion coefficients, shape (4,) fisheye or (5,) pinhole.
        rms_px: RMS reprojection error over all corners of the kept views, pixels.
        view_errors: per kept view, RMS error, pixels.
        intrinsics_std: 1-sigma of (fu, fv, cu, cv), pixels (pinhole only, else None).
        kept: indices (into the views given) of the views the fit used.
        dropped: (index, reason) of the views dropped as degenerate, in the order dropped.
        focal_guess_px: the focal length the fit started from (None: OpenCV's own start).
    """

    K: FloatArray
    dist: FloatArray
    rms_px: float
    view_errors: list[float]
    intrinsics_std: FloatArray | None
    kept: list[int]
    dropped: list[tuple[int, str]]
    focal_guess_px: float | None


def focal_estimate(views: Sequence[BoardCorners], resolution: tuple[int, int]) -> float:
    """A fisheye focal length (pixels) from board corners: the candidate of `FOCAL_GRID` under
    which the corners, undistorted by the equidistant model, best fit one homography a view.

    Args:
        views: the board corners of each view.
        resolution: (width, height) of the images.

    Raises:
        ValueError: no candidate fits (fewer than 4 corners in every view).
    """
    width, height = resolution
    centre = ((width - 1) / 2.0, (height - 1) / 2.0)
    best, best_f = np.inf, 0.0
    for f in FOCAL_GRID * width:
        score = _straightness_px(views, float(f), centre)
        if score < best:
            best, best_f = score, float(f)
    if not np.isfinite(best):
        raise ValueError("no focal length fits the corners (each view needs 4 or more)")
    return best_f


def _straightness_px(views: Sequence[BoardCorners], f: float, centre: tuple[float, float]) -> float:
    """RMS homography residual (about pixels) of the corners undistorted with focal f."""
    K = np.array([[f, 0.0, centre[0]], [0.0, f, centre[1]], [0.0, 0.0, 1.0]])
    sq: list[float] = []
    for v in views:
        if len(v) < 4:
            continue
        n = cv2.fisheye.undistortPoints(v.image_points.reshape(-1, 1, 2), K, np.zeros(4))
        n = np.asarray(n, dtype=np.float64).reshape(-1, 2)
        if not np.all(np.isfinite(n)):
            return np.inf  # corners beyond 90 deg off the axis: f is too small
        board = v.object_points[:, :2]
        H, _ = cv2.findHomography(board, n, 0)
        if H is None:
            return np.inf
        p = np.asarray(cv2.perspectiveTransform(board.reshape(-1, 1, 2), H)).reshape(-1, 2)
        # a normalized-plane distance near radius r is about (1 + r^2) times the angle
        d = np.hypot(*(p - n).T) / (1.0 + np.sum(n**2, axis=1))
        sq.append(float(np.mean(d**2)))
    return f * float(np.sqrt(np.mean(sq))) if sq else np.inf


def fit_lens(
    views: Sequence[BoardCorners],
    resolution: tuple[int, int],
    model: str,
    *,
    min_views: int,
) -> LensFit:
    """Calibrate from board corners, dropping degenerate views one at a time.

    Args:
        views: board corners per view.
        resolution: (width, height).
        model: "fisheye" (starts from `focal_estimate`) or "pinhole" (OpenCV's own start,
            Zhang's closed form, which needs no guess).
        min_views: fewest views to keep.

    Raises:
        ValueError: OpenCV fails on every subset tried (the message names the views dropped
            and OpenCV's error).
    """
    guess = focal_estimate(views, resolution) if model == "fisheye" else None
    kept = list(range(len(views)))
    dropped: list[tuple[int, str]] = []
    while True:
        try:
            return _finish(
                _fit([views[i] for i in kept], resolution, model, guess), kept, dropped, guess
            )
        except _FitError as failure:
            error = failure.message
        if len(kept) <= min_views:
            break
        trials: list[tuple[float, int]] = []
        for i in kept:
            rest = [views[j] for j in kept if j != i]
            try:
                trials.append((_fit(rest, resolution, model, guess)[2], i))
            except _FitError:
                continue
        if not trials:
            break
        worst = min(trials)[1]
        dropped.append((worst, f"degenerate: the {model} fit fails with this view ({error})"))
        kept.remove(worst)
    names = ", ".join(f"view {i}" for i, _ in dropped)
    raise ValueError(
        f"OpenCV could not calibrate the {model} model from {len(kept)} views ({error})"
        + (f" even after dropping {names}" if dropped else "")
        + "; add views with the board tilted (up to ~45 deg) and spread over the whole image"
    )


class _FitError(Exception):
    def __init__(self, message: str) -> None:
        super().__init__(message)
        self.message = message


_Raw = tuple[FloatArray, FloatArray, float, list[float], FloatArray | None]


def _finish(
    raw: _Raw, kept: list[int], dropped: list[tuple[int, str]], guess: float | None
) -> LensFit:
    K, dist, rms, errors, std = raw
    return LensFit(K, dist, rms, errors, std, list(kept), list(dropped), guess)


def _fit(
    views: Sequence[BoardCorners], resolution: tuple[int, int], model: str, guess: float | None
) -> _Raw:
    """One OpenCV calibration: (K, dist, rms, per-view errors, intrinsics std)."""
    try:
        if model == "fisheye":
            obj = [np.ascontiguousarray(v.object_points.reshape(1, -1, 3)) for v in views]
            img = [np.ascontiguousarray(v.image_points.reshape(1, -1, 2)) for v in views]
            flags = cv2.CALIB_RECOMPUTE_EXTRINSIC | cv2.CALIB_FIX_SKEW
            K0 = np.eye(3)
            if guess is not None:
                flags |= cv2.CALIB_USE_INTRINSIC_GUESS
                w, h = resolution
                K0 = np.array([[guess, 0, (w - 1) / 2], [0, guess, (h - 1) / 2], [0, 0, 1.0]])
            _, K, D, rvecs, tvecs = cv2.fisheye.calibrate(
                obj, img, resolution, K0, np.zeros(4), flags=flags, criteria=_FISHEYE_CRITERIA
            )
            std = None
            proj = [
                cv2.fisheye.projectPoints(o, r, t, K, D)[0]
                for o, r, t in zip(obj, rvecs, tvecs, strict=True)
            ]
        else:
            obj = [v.object_points.astype(np.float32) for v in views]
            img = [v.image_points.astype(np.float32) for v in views]
            out = cv2.calibrateCameraExtended(obj, img, resolution, None, None)  # type: ignore[call-overload]
            _, K, D, rvecs, tvecs, std_int = out[:6]
            std = np.asarray(std_int, dtype=np.float64).reshape(-1)[:4]
            proj = [
                cv2.projectPoints(o, r, t, K, D)[0]
                for o, r, t in zip(obj, rvecs, tvecs, strict=True)
            ]
    except cv2.error as exc:
        raise _FitError(f"OpenCV: {str(exc).strip().splitlines()[-1]}") from None
    sq = [
        np.sum((np.asarray(p, dtype=np.float64).reshape(-1, 2) - v.image_points) ** 2, axis=1)
        for p, v in zip(proj, views, strict=True)
    ]
    rms = float(np.sqrt(np.mean(np.concatenate(sq))))
    dist = np.asarray(D, dtype=np.float64).reshape(-1)
    if not np.isfinite(rms) or not np.all(np.isfinite(K)) or not np.all(np.isfinite(dist)):
        raise _FitError("the fit diverged")
    if rms > MAX_FIT_RMS_PX:
        raise _FitError(f"the fit ended {rms:.1f} px RMS off, in a wrong minimum")
    errors = [float(np.sqrt(np.mean(s))) for s in sq]
    return np.asarray(K, dtype=np.float64), dist, rms, errors, std
