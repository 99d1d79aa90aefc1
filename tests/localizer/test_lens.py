"""`pixel_from_point` (Python floats) against OpenCV's projection."""

from __future__ import annotations

import numpy as np
import pytest

from localizer.camera import pixels_from_points_camera
from localizer.lens import pixel_from_point
from sim.cameras import wide_angle_camera
from tests.localizer.cameras import LENSES, make_camera


@pytest.mark.parametrize("lens", [*LENSES, "sim-pinhole", "sim-fisheye"])
def test_pixel_from_point_matches_opencv(lens: str) -> None:
    sim = lens.startswith("sim-")
    cam = wide_angle_camera(lens[4:]) if sim else make_camera(lens)  # type: ignore[arg-type]
    rng = np.random.default_rng(7)
    # points over a wide cone (some outside the field of view or the image) and a few behind
    p = np.column_stack([rng.uniform(-4, 4, (400, 2)), rng.uniform(0.5, 3.0, 400)])
    p[:10, 2] *= -1
    p[10] = (0.0, 0.0, 2.0)  # on the axis: the fisheye's r = 0 branch
    px, valid = pixels_from_points_camera(cam, p)
    got = [pixel_from_point(cam, *map(float, q)) for q in p]
    assert [g is not None for g in got] == valid.tolist()
    assert 50 < np.count_nonzero(valid) < 390  # both outcomes are exercised
    ours = np.array([g for g in got if g is not None])
    np.testing.assert_allclose(ours, px[valid], rtol=0, atol=1e-9)
