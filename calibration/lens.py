"""Lens calibration (Zhang's method, as the paper) from decoded photos of a board.

Pinhole with radial-tangential distortion (`cv2.calibrateCamera`) or equidistant fisheye
(`cv2.fisheye.calibrate`). The core takes decoded images as numpy arrays and writes nothing;
`calibration.cli` and `calibration.uploads` do the file and upload handling.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
import numpy.typing as npt

from calibration.board import BoardCorners, BoardSpec, as_gray, find_board, suggest_pattern
from calibration.coverage import Coverage, corner_coverage
from calibration.lens_fit import fit_lens
from localizer.camera import CameraModel, T_body_camera_upward, sensor_from_camera
from localizer.types import FloatArray, ImageU8

LensModel = Literal["pinhole", "fisheye"]
LENS_MODELS: tuple[LensModel, ...] = ("pinhole", "fisheye")


@dataclass(frozen=True)
class LensCalibrationConfig:
    """Tuning of the lens calibration.

    Attributes:
        min_views: fewest usable views (Zhang needs 3; 10-20 spread over the image are better).
        outlier_factor: a view whose RMS error exceeds this many times the median view's ...
        outlier_min_px: ... and also this many pixels is dropped and the calibration rerun.
        coverage_cells: coverage grid (columns, rows).
        min_outer_coverage: warn when fewer of the border cells than this share held a corner.
        recommended_views: warn when fewer photos than this were given (15-25 spread over
            the image, docs/calibration.md).
    """

    min_views: int = 5
    outlier_factor: float = 3.0
    outlier_min_px: float = 1.0
    coverage_cells: tuple[int, int] = (8, 6)
    min_outer_coverage: float = 0.5
    recommended_views: int = 15


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
    advice = _input_warnings(grays, labels, reasons, spec, cfg)
    if len(usable) < cfg.min_views:
        raise ValueError(
            f"only {len(usable)} of {len(grays)} images show the board; need at least "
            f"{cfg.min_views} views"
            + _rejected(labels, reasons)
            + "".join(f"; {w}" for w in advice)
        )

    fit = fit_lens([corners[i] for i in usable], resolution, model, min_views=cfg.min_views)  # type: ignore[misc]
    for k, why in fit.dropped:
        reasons[usable[k]] = why
    usable = [usable[k] for k in fit.kept]
    errors = dict(zip(usable, fit.view_errors, strict=True))
    limit = max(cfg.outlier_factor * float(np.median(fit.view_errors)), cfg.outlier_min_px)
    outliers = [i for i in usable if errors[i] > limit]
    if outliers and len(usable) - len(outliers) >= cfg.min_views:
        for i in outliers:
            reasons[i] = f"outlier: error {errors[i]:.2f} px > {limit:.2f} px"
        usable = [i for i in usable if i not in outliers]
        refit = fit_lens(
            [corners[i] for i in usable],  # type: ignore[misc]
            resolution,
            model,
            min_views=cfg.min_views,
        )
        for k, why in refit.dropped:
            reasons[usable[k]] = why
        usable = [usable[k] for k in refit.kept]
        fit = refit
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
        warnings=tuple(advice + _warnings(coverage, fit.rms_px, model, cfg)),
        intrinsics_std=fit.intrinsics_std,
        board=spec,
    )


def _common_resolution(
    grays: Sequence[ImageU8],
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


def _no_board_message(grays: Sequence[ImageU8], names: Sequence[str], spec: BoardSpec) -> str:
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


def _rejected(labels: Sequence[str], reasons: Sequence[str | None]) -> str:
    """'. Rejected: a: why; b: why' for the views with a reason, '' when there are none."""
    parts = [f"{name}: {why}" for name, why in zip(labels, reasons, strict=True) if why]
    return ". Rejected: " + "; ".join(parts) if parts else ""


def _input_warnings(
    grays: Sequence[ImageU8],
    labels: Sequence[str],
    reasons: Sequence[str | None],
    spec: BoardSpec,
    cfg: LensCalibrationConfig,
) -> list[str]:
    """Advice on the photo set itself: too few photos, a pattern most photos do not show."""
    out = []
    if len(grays) < cfg.recommended_views:
        out.append(
            f"only {len(grays)} photos given; {cfg.recommended_views}-25 spread over the whole "
            "image (edges and corners too) are recommended"
        )
    missing = [i for i, r in enumerate(reasons) if r == "no board found"]
    if spec.kind == "chessboard" and 2 * len(missing) > len(grays):
        cols, rows = spec.pattern
        hint = next(
            (
                (labels[i], h)
                for i in missing[:3]
                if (h := suggest_pattern(grays[i], spec.pattern)) is not None
            ),
            None,
        )
        text = (
            f"the {cols}x{rows} pattern was found on only {len(grays) - len(missing)} of "
            f"{len(grays)} photos"
        )
        if hint is not None:
            text += f"; {hint[0]} shows a {hint[1][0]}x{hint[1][1]} board: check --pattern"
        else:
            text += "; check --pattern (inner corners, columns x rows)"
        out.append(text)
    return out


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
