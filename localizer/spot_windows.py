"""Spots inside search windows only: the tracking fast path (Sec. IV-A.1).

While tracking, a landmark's spot is searched only in a window around its predicted pixel
(array slices, no full-frame operation). A window usually holds one compact spot: it is
measured without labelling (`_single_spot`: one threshold, its bounding box and pixel count);
anything else is labelled as in a full frame (`spots.spots_in_region`). The detector's
thresholds, shape filters and centroid are those of `spots.py`.
"""

from __future__ import annotations

from collections.abc import Sequence

import cv2
import numpy as np
import numpy.typing as npt

from localizer.spots import (
    DetectionConfig,
    SpotRow,
    Spots,
    append_centroid,
    brightest,
    check_image,
    estimate_background,
    spots_in_region,
    threshold_for,
    window_boxes,
)
from localizer.types import ImageU8


def detect_spots_in_windows(
    image: ImageU8,
    centers: npt.ArrayLike,
    half_sizes: npt.ArrayLike,
    config: DetectionConfig,
    *,
    background: tuple[float, float] | None = None,
) -> Spots:
    """Detect spots only inside search windows (the tracking fast path, Sec. IV-A.1).

    Overlapping windows are merged into their bounding box so that a spot is found once.

    Args:
        image: 8-bit grayscale frame, shape (H, W).
        centers: window centres (col, row), pixels, shape (M, 2).
        half_sizes: half widths and heights of the windows, pixels, shape (M, 2).
        config: detector tuning.
        background: (level, noise) counts; None estimates them from the frame (a strided
            subsample, not a full-frame pass); pass the last known values to save that.

    Returns:
        The spots inside the windows.
    """
    check_image(image)
    c = np.asarray(centers, dtype=np.float64).reshape(-1, 2)
    hs = np.asarray(half_sizes, dtype=np.float64).reshape(-1, 2)
    if len(c) != len(hs):
        raise ValueError(f"detect_spots_in_windows: {len(c)} centers but {len(hs)} half sizes")
    if len(c) == 0:
        return Spots.empty()
    bg_noise = estimate_background(image, config) if background is None else background
    return Spots.from_lists(spot_rows_in_windows(image, c.tolist(), hs.tolist(), config, bg_noise))


def spot_rows_in_windows(
    image: ImageU8,
    centers: Sequence[Sequence[float]],
    half_sizes: Sequence[Sequence[float]],
    config: DetectionConfig,
    background: tuple[float, float],
) -> list[SpotRow]:
    """`detect_spots_in_windows` on Python lists, unchecked: the localizer's hot path.

    Args:
        image: 8-bit grayscale frame, shape (H, W).
        centers, half_sizes: per window (col, row) and (half width, half height), pixels.
        background: (level, noise), counts.

    Returns:
        (col, row, intensity, area) of each spot, at most `config.max_spots`.
    """
    bg, noise = background
    thr = threshold_for(bg, noise, config)
    H, W = image.shape
    rows: list[SpotRow] = []
    for c0, r0, c1, r1 in window_boxes(centers, half_sizes, W, H):
        region = image[r0:r1, c0:c1]
        _, peak, _, loc = cv2.minMaxLoc(region)
        if peak <= thr:
            continue
        edge = config.drop_border_blobs  # the image's border cuts too
        cut = (c0 > 0 or edge, r0 > 0 or edge, c1 < W or edge, r1 < H or edge)
        if not _single_spot(region, loc, peak, (c0, r0), bg, thr, config, rows, cut):
            spots_in_region(region, (c0, r0), bg, thr, config, rows, cut_sides=cut)
    return brightest(rows, config.max_spots)


_FAST_RADIUS_PX = 4


def _single_spot(
    region: ImageU8,
    peak_loc: Sequence[int],
    peak: float,
    origin: tuple[int, int],
    background: float,
    threshold: float,
    config: DetectionConfig,
    out: list[SpotRow],
    cut_sides: tuple[bool, bool, bool, bool],
) -> bool:
    """The usual tracking case without labelling: one compact spot around the peak.

    Returns False (the caller labels the region) unless every above-threshold pixel of the
    region lies well inside a small patch around the peak, i.e. the region holds exactly one
    small blob; its shape is then checked like `_spots_in_region` does.
    """
    rh, rw = region.shape
    r = _FAST_RADIUS_PX
    x, y = peak_loc
    # (conditional expressions: cheaper than min/max calls on this hot path)
    c0, r0 = (x - r if x > r else 0), (y - r if y > r else 0)
    c1, r1 = (x + r + 1 if x + r + 1 < rw else rw), (y + r + 1 if y + r + 1 < rh else rh)
    _, binary = cv2.threshold(region, threshold, 1, cv2.THRESH_BINARY)
    bx, by, w, h = cv2.boundingRect(binary)  # of every pixel above the threshold
    if bx < c0 or by < r0 or bx + w > c1 or by + h > r1:
        return False  # pixels above the threshold outside the patch: label the region
    # The blob must not touch the patch's edge unless that edge is the image's border.
    if (
        (bx == c0 and (c0 > 0 or cut_sides[0]))
        or (by == r0 and (r0 > 0 or cut_sides[1]))
        or (bx + w == c1 and (c1 < rw or cut_sides[2]))
        or (by + h == r1 and (r1 < rh or cut_sides[3]))
    ):
        return False
    area = cv2.countNonZero(binary)
    if (
        config.min_area_px <= area <= config.max_area_px
        and area / (w * h) >= config.min_fill_ratio
        and (w / h if w > h else h / w) <= config.max_elongation
    ):
        append_centroid(region, (bx, by, w, h), origin, background, float(area), config, out, peak)
    return True  # one blob (kept, or rejected by the filters)
