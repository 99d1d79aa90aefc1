"""How well the calibration corners covered the image.

Lens distortion is only measured where corners were seen: a wide-angle lens calibrated from
photos with the board in the middle extrapolates its distortion at the edges, where the
landmarks near the horizon appear. The image is cut into a coarse grid; the outer band is
the ring of grid cells along the border.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from localizer.types import FloatArray, IntArray


@dataclass(frozen=True, eq=False)
class Coverage:
    """Corner counts on a coarse grid over the image.

    Attributes:
        counts: corners per cell, shape (rows, cols) of the grid.
        fraction: share of cells holding at least one corner, 0..1.
        outer_fraction: share of the border ring's cells holding at least one corner, 0..1.
    """

    counts: IntArray
    fraction: float
    outer_fraction: float

    def to_dict(self) -> dict[str, object]:
        """JSON-ready mapping."""
        return {
            "grid": self.counts.tolist(),
            "fraction": self.fraction,
            "outer_fraction": self.outer_fraction,
        }


def corner_coverage(
    image_points: Sequence[FloatArray],
    resolution: tuple[int, int],
    *,
    cells: tuple[int, int] = (8, 6),
) -> Coverage:
    """Count corners per grid cell.

    Args:
        image_points: per view, pixels of shape (N, 2).
        resolution: (width, height) in pixels.
        cells: grid size (columns, rows), each >= 3 so that the grid has an inside.

    Returns:
        The coverage of the image by all views' corners.
    """
    n_cols, n_rows = cells
    if n_cols < 3 or n_rows < 3:
        raise ValueError(f"coverage grid must be at least 3x3 cells, got {cells}")
    width, height = resolution
    counts = np.zeros((n_rows, n_cols), dtype=np.int64)
    if image_points:
        pts = np.concatenate([np.asarray(p, dtype=np.float64).reshape(-1, 2) for p in image_points])
        col = np.clip(((pts[:, 0] + 0.5) / width * n_cols).astype(np.int64), 0, n_cols - 1)
        row = np.clip(((pts[:, 1] + 0.5) / height * n_rows).astype(np.int64), 0, n_rows - 1)
        np.add.at(counts, (row, col), 1)
    border = np.ones_like(counts, dtype=bool)
    border[1:-1, 1:-1] = False
    hit = counts > 0
    return Coverage(
        counts=counts,
        fraction=float(np.mean(hit)),
        outer_fraction=float(np.mean(hit[border])),
    )
