"""Lens calibration (Zhang's method, as the paper) from decoded photos of a board.

Pinhole with radial-tangential distortion (`cv2.calibrateCamera`) or equidistant fisheye
(`cv2.fisheye.calibrate`). The core takes decoded images as numpy arrays and writes nothing;
`calibration.cli` and `calibration.uploads` do the file and upload handling.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

import cv2
import numpy as np
import numpy.typing as npt

from calibration.board import BoardCorners, BoardSpec, as_gray, find_board, suggest_pattern
from calibration.coverage import Coverage, corner_coverage
from localizer.camera import CameraModel, T_body_camera_upward, sensor_from_camera

FloatArray = npt.NDArray[np.float64]
LensModel = Literal["pinhole", "fisheye"]
LENS_MODELS: tuple[LensModel, ...] = ("pinhole", "fisheye")

_FISHEYE_CRITERIA = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 200, 1e-12)


@dataclass(frozen=True)
class LensCalibrationConfig:
    """Tuning of the lens calibration.

    Attributes:
        min_views: fewest usable views (Zhang needs 3; 10-20 spread over the image are better).
        outlier_factor: a view whose RMS error exceeds this many times the median view's ...
        outlier_min_px: ... and also this many pixels is dropped and the calibration rerun.
        coverage_cells: coverage grid (columns, rows).
        min_outer_coverage: warn when fewer of the border cells than this share held a corner.
    """

    min_views: int = 5
    outlier_factor: float = 3.0
    outlier_min_px: float = 1.0
    coverage_cells: tuple[int, int] = (8, 6)
    min_outer_coverage: float = 0.5


@dataclass(frozen=True)
class ViewReport:
    """What happened to one photo.

    Attributes:
        name: file name or label.
        corners: board corners found (0 when none).
        error_px: RMS reprojection error of this view's corners, pixels (None if unused
            before the calibration ran).
        used: True when the view entered the final calibration.
        reason: why it was rejected, or None.
    """

    name: str
    corners: int
    error_px: float | None
    used: bool
    reason: str | None = None


@dataclass(frozen=True, eq=False)
class LensCalibration:
    """The result of a lens calibration.

    Attributes:
        camera: the calibrated camera (mounting as given to `calibrate_lens`).
        model: "pinhole" or "fisheye".
        rms_px: RMS reprojection error over all corners of the used views, pixels.
        views: one report per input image, in input order.
        coverage: corner coverage of the image by the used views.
        warnings: advice for the user (poor coverage, high error).
        intrinsics_std: 1-sigma of (fu, fv, cu, cv) in pixels (pinhole only, else None).
        board: the board that was used.
    """

    camera: CameraModel
    model: LensModel
    rms_px: float
    views: tuple[ViewReport, ...]
    coverage: Coverage
    warnings: tuple[str, ...]
    intrinsics_std: FloatArray | None
    board: BoardSpec = field(default_factory=BoardSpec)

    @property
    def used_views(self) -> int:
        return sum(v.used for v in self.views)

    def sensor(self) -> dict[str, Any]:
        """The EuRoC `sensor.yaml` mapping of the calibrated camera."""
        return sensor_from_camera(self.camera)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready mapping: sensor.yaml, errors, per-view reports, coverage, warnings."""
        std = None if self.intrinsics_std is None else [float(x) for x in self.intrinsics_std]
        return {
            "model": self.model,
            "sensor": self.sensor(),
            "rms_px": self.rms_px,
            "intrinsics_std_px": std,
            "board": {
                "kind": self.board.kind,
                "pattern": list(self.board.pattern),
                "square_m": self.board.square_m,
            },
            "views": [
                {
                    "name": v.name,
                    "corners": v.corners,
                    "error_px": v.error_px,
                    "used": v.used,
                    "reason": v.reason,
                }
                for v in self.views
            ],
            "used_views": self.used_views,
            "coverage": self.coverage.to_dict(),
            "warnings": list(self.warnings),
        }

    def summary(self) -> str:
        """A plain-text table: per view corners and error, totals, intrinsics, coverage."""
        width = max([len(v.name) for v in self.views] + [4])
        lines = [f"{'view':<{width}}  corners  error_px  status"]
        for v in self.views:
            err = "-" if v.error_px is None else f"{v.error_px:.3f}"
            status = "used" if v.used else f"rejected: {v.reason}"
            lines.append(f"{v.name:<{width}}  {v.corners:>7}  {err:>8}  {status}")
        cam = self.camera
        lines += [
            "",
            f"views used: {self.used_views} of {len(self.views)}   RMS error: {self.rms_px:.3f} px",
            f"model: {self.model} ({cam.distortion_model})  resolution: {cam.width}x{cam.height}",
            f"fu fv cu cv: {cam.fu:.2f} {cam.fv:.2f} {cam.cu:.2f} {cam.cv:.2f}",
            "distortion: " + " ".join(f"{d:.5f}" for d in cam.distortion),
            f"coverage: {100 * self.coverage.fraction:.0f}% of the image grid, "
            f"{100 * self.coverage.outer_fraction:.0f}% of its outer band",
        ]
        lines += [f"warning: {w}" for w in self.warnings]
        return "\n".join(lines)


def calibrate_lens(
    images: Sequence[npt.NDArray[np.generic]],
    *,
    pattern: tuple[int, int] = (9, 6),
    square_m: float = 0.025,
    model: LensModel = "pinhole",
    names: Sequence[str] | None = None,
    board: BoardSpec | None = None,
    expected_resolution: tuple[int, int] | None = None,
    T_body_camera: FloatArray | None = None,
    rate_hz: float = 30.0,
    config: LensCalibrationConfig | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> LensCalibration:
    """Calibrate the lens from photos of a board.

    Args:
        images: decoded photos (gray or BGR, uint8/uint16), each (H, W) or (H, W, C).
        pattern: inner corners (columns, rows) of a chessboard; ignored when `board` is given.
        square_m: side of a square, metres; ignored when `board` is given.
        model: "pinhole" (radial-tangential k1 k2 p1 p2 k3) or "fisheye" (equidistant).
        names: a label per image for the reports (file names); default "view <i>".
        board: the board (e.g. a ChArUco board); default a chessboard of `pattern`, `square_m`.
        expected_resolution: (width, height); views of another size are rejected. Without it,
            mixed sizes are an error.
        T_body_camera: mounting to put into the result, shape (4, 4); default the reference
            upward mounting `T_body_camera_upward()`.
        rate_hz: frame rate to put into the result.
        config: tuning.
        progress: called as progress(done, total) after each image is searched.

    Returns:
        The calibration (the views rejected and why are in `views`).

    Raises:
        ValueError: no board in any image (with a hint on the pattern size), mixed
            resolutions, too few usable views, bad arguments or a calibration that fails.
    """
    cfg = config or LensCalibrationConfig()
    if model not in LENS_MODELS:
        raise ValueError(f"lens model must be one of {LENS_MODELS}, got {model!r}")
    spec = board or BoardSpec(pattern=pattern, square_m=square_m)
    labels = [f"view {i}" for i in range(len(images))] if names is None else list(names)
    if len(labels) != len(images):
        raise ValueError(f"got {len(images)} images but {len(labels)} names")
    if not images:
        raise ValueError("no images given")
    grays = [as_gray(img, name) for img, name in zip(images, labels, strict=True)]
    resolution = _common_resolution(grays, labels, expected_resolution)

    corners: list[BoardCorners | None] = []
    reasons: list[str | None] = []
    for i, gray in enumerate(grays):
        size = (gray.shape[1], gray.shape[0])
        if size != resolution:
            corners.append(None)
            reasons.append(f"wrong resolution {size[0]}x{size[1]}")
        else:
            found = find_board(gray, spec)
            corners.append(found)
            reasons.append(None if found is not None else "no board found")
        if progress is not None:
            progress(i + 1, len(grays))

    usable = [i for i, c in enumerate(corners) if c is not None]
    if not usable:
        if all(r is not None and r.startswith("wrong resolution") for r in reasons):
            raise ValueError(
                f"none of the {len(grays)} images has the expected resolution "
                f"{resolution[0]}x{resolution[1]}"
            )
        raise ValueError(_no_board_message(grays, labels, spec))
    if len(usable) < cfg.min_views:
        raise ValueError(
            f"only {len(usable)} of {len(grays)} images show the board; need at least "
            f"{cfg.min_views} views. Rejected: "
            + "; ".join(f"{labels[i]}: {reasons[i]}" for i in range(len(grays)) if reasons[i])
        )

    views = [c for c in corners if c is not None]
    fit = _calibrate(views, resolution, model)
    errors = dict(zip(usable, fit.view_errors, strict=True))
    limit = max(cfg.outlier_factor * float(np.median(fit.view_errors)), cfg.outlier_min_px)
    outliers = [i for i in usable if errors[i] > limit]
    if outliers and len(usable) - len(outliers) >= cfg.min_views:
        for i in outliers:
            reasons[i] = f"outlier: error {errors[i]:.2f} px > {limit:.2f} px"
        usable = [i for i in usable if i not in outliers]
        fit = _calibrate([corners[i] for i in usable], resolution, model)  # type: ignore[misc]
        errors.update(zip(usable, fit.view_errors, strict=True))

    T = T_body_camera_upward() if T_body_camera is None else T_body_camera
    K, dist = fit.K, fit.dist
    try:
        camera = CameraModel(
            width=resolution[0],
            height=resolution[1],
            fu=float(K[0, 0]),
            fv=float(K[1, 1]),
            cu=float(K[0, 2]),
            cv=float(K[1, 2]),
            distortion_model="equidistant" if model == "fisheye" else "radial-tangential",
            distortion=dist,
            T_body_camera=T,
            rate_hz=rate_hz,
        )
    except ValueError as exc:
        raise ValueError(f"calibration failed: {exc}") from None
    used_points = [corners[i].image_points for i in usable]  # type: ignore[union-attr]
    coverage = corner_coverage(used_points, resolution, cells=cfg.coverage_cells)
    reports = tuple(
        ViewReport(
            name=labels[i],
            corners=0 if corners[i] is None else len(corners[i]),  # type: ignore[arg-type]
            error_px=errors.get(i),
            used=i in usable,
            reason=reasons[i],
        )
        for i in range(len(grays))
    )
    return LensCalibration(
        camera=camera,
        model=model,
        rms_px=fit.rms_px,
        views=reports,
        coverage=coverage,
        warnings=tuple(_warnings(coverage, fit.rms_px, model, cfg)),
        intrinsics_std=fit.intrinsics_std,
        board=spec,
    )


@dataclass(frozen=True, eq=False)
class _Fit:
    K: FloatArray
    dist: FloatArray
    rms_px: float
    view_errors: list[float]
    intrinsics_std: FloatArray | None


def _calibrate(views: Sequence[BoardCorners], resolution: tuple[int, int], model: str) -> _Fit:
    """Run OpenCV's calibration and measure each view's RMS reprojection error."""
    try:
        if model == "fisheye":
            obj = [np.ascontiguousarray(v.object_points.reshape(1, -1, 3)) for v in views]
            img = [np.ascontiguousarray(v.image_points.reshape(1, -1, 2)) for v in views]
            flags = cv2.CALIB_RECOMPUTE_EXTRINSIC | cv2.CALIB_FIX_SKEW
            _, K, D, rvecs, tvecs = cv2.fisheye.calibrate(
                obj, img, resolution, np.eye(3), np.zeros(4), flags=flags,
                criteria=_FISHEYE_CRITERIA,
            )  # fmt: skip
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
        raise ValueError(
            f"OpenCV could not calibrate the {model} model from {len(views)} views "
            f"({str(exc).strip().splitlines()[-1]}); add views with the board tilted and "
            "spread over the whole image"
        ) from None
    sq = [
        np.sum((np.asarray(p, dtype=np.float64).reshape(-1, 2) - v.image_points) ** 2, axis=1)
        for p, v in zip(proj, views, strict=True)
    ]
    view_errors = [float(np.sqrt(np.mean(s))) for s in sq]
    rms = float(np.sqrt(np.mean(np.concatenate(sq))))
    dist = np.asarray(D, dtype=np.float64).reshape(-1)
    if not np.isfinite(rms) or not np.all(np.isfinite(K)) or not np.all(np.isfinite(dist)):
        raise ValueError(f"the {model} calibration diverged; add views spread over the image")
    return _Fit(np.asarray(K, dtype=np.float64), dist, rms, view_errors, std)


def _common_resolution(
    grays: Sequence[npt.NDArray[np.uint8]],
    names: Sequence[str],
    expected: tuple[int, int] | None,
) -> tuple[int, int]:
    """The resolution all views must share; ValueError on mixed sizes without `expected`."""
    if expected is not None:
        return (int(expected[0]), int(expected[1]))
    groups: dict[tuple[int, int], list[str]] = {}
    for gray, name in zip(grays, names, strict=True):
        groups.setdefault((gray.shape[1], gray.shape[0]), []).append(name)
    if len(groups) > 1:
        parts = [
            f"{w}x{h} ({len(n)} image{'s' if len(n) > 1 else ''}: {', '.join(n[:3])}"
            f"{', ...' if len(n) > 3 else ''})"
            for (w, h), n in sorted(groups.items(), key=lambda kv: -len(kv[1]))
        ]
        raise ValueError(
            "mixed image resolutions: " + "; ".join(parts) + ". All photos must come from "
            "the calibrated camera at the resolution it will run at"
        )
    return next(iter(groups))


def _no_board_message(
    grays: Sequence[npt.NDArray[np.uint8]], names: Sequence[str], spec: BoardSpec
) -> str:
    cols, rows = spec.pattern
    msg = f"no {spec.kind} with {cols}x{rows} inner corners found in any of the {len(grays)} images"
    if spec.kind == "chessboard":
        for gray, name in list(zip(grays, names, strict=True))[:2]:
            hint = suggest_pattern(gray, spec.pattern)
            if hint is not None:
                return msg + (
                    f"; a {hint[0]}x{hint[1]} board was found in {name}: try --pattern "
                    f"{hint[0]}x{hint[1]}"
                )
    return msg + (
        "; check --pattern: it counts inner corners (where four squares meet), so a board of "
        f"{cols + 1}x{rows + 1} squares has a {cols}x{rows} pattern"
    )


def _warnings(
    coverage: Coverage, rms_px: float, model: str, cfg: LensCalibrationConfig
) -> list[str]:
    out = []
    if coverage.outer_fraction < cfg.min_outer_coverage:
        out.append(
            f"the corners covered only {100 * coverage.outer_fraction:.0f}% of the image's "
            "outer band: the distortion at the edges is extrapolated"
            + (" (a wide-angle lens needs it measured there)" if model == "fisheye" else "")
            + "; add photos with the board near the edges and corners"
        )
    if rms_px > 1.0:
        out.append(f"RMS error {rms_px:.2f} px is high: check focus, motion blur and a flat board")
    return out
