"""The camera's projection of one point on Python floats, for the tracking hot path.

`camera.pixels_from_points_camera` goes through OpenCV, whose per-call cost (~10-20 us with
the array handling) dominates when a frame predicts three landmarks. `pixel_from_point`
writes out the same models (OpenCV's `projectPoints` radial-tangential k1 k2 p1 p2 [k3] and
`fisheye.projectPoints` equidistant k1-k4) for one point; the tests hold it to OpenCV's
result. The inverse (undistortion, iterative) stays with OpenCV.
"""

from __future__ import annotations

import math

from localizer.camera import CameraModel


def pixel_from_point(
    camera: CameraModel, x: float, y: float, z: float
) -> tuple[float, float] | None:
    """Pixel of a point in the camera frame (metres), as `pixels_from_points_camera`.

    Returns:
        (col, row), or None when the point is not valid there: behind the camera, outside
        the lens's field of view, or projecting outside the image.
    """
    if z <= 1e-9 or z < camera.cos_max_angle * math.sqrt(x * x + y * y + z * z):
        return None
    a, b = x / z, y / z
    k = camera.coefficients
    if camera.distortion_model == "equidistant":
        r = math.sqrt(a * a + b * b)
        if r > 1e-8:
            t = math.atan(r)
            t2 = t * t
            scale = t * (1 + t2 * (k[0] + t2 * (k[1] + t2 * (k[2] + t2 * k[3])))) / r
            a, b = a * scale, b * scale
    else:
        k1, k2, p1, p2 = k[:4]
        k3 = k[4] if len(k) > 4 else 0.0
        r2 = a * a + b * b
        radial = 1 + k1 * r2 + k2 * r2 * r2 + k3 * r2 * r2 * r2
        ab2 = 2 * a * b
        a, b = (
            a * radial + p1 * ab2 + p2 * (r2 + 2 * a * a),
            b * radial + p1 * (r2 + 2 * b * b) + p2 * ab2,
        )
    u, v = camera.fu * a + camera.cu, camera.fv * b + camera.cv
    if not (-0.5 <= u <= camera.width - 0.5 and -0.5 <= v <= camera.height - 0.5):
        return None
    return u, v
