"""Line-segment nodes of the 3D scene: a polyline as segments, and a segments node replaced
in one colour (robots' trails and rays, footprints, the survey's suggested route)."""

from __future__ import annotations

import numpy as np
import viser

from localizer.types import FloatArray
from web.colors import RGB


def polyline_segments(points: FloatArray) -> FloatArray:
    """Consecutive points as line segments: (N, 3) -> (N - 1, 2, 3)."""
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if len(p) < 2:
        return np.zeros((0, 2, 3))
    return np.stack([p[:-1], p[1:]], axis=1)


def set_segments(handle: viser.LineSegmentsHandle, segments: FloatArray, color: RGB) -> None:
    """Replace a line-segments node's segments (N, 2, 3), all in one colour (the colours
    are only sent when their number or the colour changed; call inside `server.atomic()`
    so that a browser applies both together)."""
    seg = np.asarray(segments, dtype=np.float32).reshape(-1, 2, 3)
    colors = handle.colors
    if colors.shape != seg.shape or (len(seg) > 0 and tuple(colors[0, 0]) != tuple(color)):
        handle.colors = np.broadcast_to(np.array(color, dtype=np.uint8), seg.shape).copy()
    handle.points = seg
