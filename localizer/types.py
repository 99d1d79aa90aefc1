"""The array and pose types every package shares, defined once.

Arrays carry their dtype in the name; shapes are stated where they are used (docstrings
say "shape (N, 2)"). A `Pose` is a planar pose in the map frame (REP-103): x and y in
metres, the heading theta in radians, counter-clockwise from +x, in (-pi, pi].
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]
BoolArray = npt.NDArray[np.bool_]
ImageU8 = npt.NDArray[np.uint8]  # a gray (H, W) or colour (H, W, 3) 8-bit image

Pose = tuple[float, float, float]  # (x m, y m, theta rad)

__all__ = ["BoolArray", "FloatArray", "ImageU8", "IntArray", "Pose"]
