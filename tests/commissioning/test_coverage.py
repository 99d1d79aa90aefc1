from __future__ import annotations

import numpy as np
import pytest

from commissioning.coverage import CoverageConfig, coverage_grid, spacing_flags
from localizer.camera import predict_pixels
from localizer.geometry import T_world_body_from_pose
from sim.cameras import wide_angle_camera


def test_counts_match_predict_pixels_at_one_heading() -> None:
    cam = wide_angle_camera("pinhole")
    rng = np.random.default_rng(3)
    lm = np.column_stack([rng.uniform(0, 6, 12), rng.uniform(0, 4, 12), np.full(12, 2.5)])
    cfg = CoverageConfig(step_m=1.0, n_headings=1)
    cov = coverage_grid(cam, lm, cfg, bounds=(0.0, 6.0, 0.0, 4.0))
    assert cov.counts.shape == (5, 7)
    for r, y in enumerate(cov.ys):
        for c, x in enumerate(cov.xs):
            _, valid = predict_pixels(cam, T_world_body_from_pose(x, y, 0.0), lm)
            assert cov.counts[r, c] == int(valid.sum())


def test_error_shrinks_with_baseline_and_grows_with_height() -> None:
    cam = wide_angle_camera("pinhole")
    cfg = CoverageConfig(step_m=1.0, n_headings=1)

    def err(spacing: float, z: float) -> float:
        lm = [[-spacing / 2, 0.0, z], [spacing / 2, 0.0, z]]
        # off to the side: the heading error moves the position through the lever arm
        c = coverage_grid(cam, lm, cfg, bounds=(0.0, 0.0, 0.8, 0.8))
        assert c.counts[0, 0] == 2
        return float(c.error_m[0, 0])

    assert err(1.0, 2.5) < err(0.3, 2.5)
    assert err(0.6, 2.5) < err(0.6, 4.0)
    # order of magnitude: 0.3 px noise, f = 320 px, 2.2 m above the camera -> millimetres
    assert 1e-4 < err(1.0, 2.5) < 1e-2


def test_one_or_no_landmark_gives_no_error_estimate() -> None:
    cam = wide_angle_camera("fisheye")
    cov = coverage_grid(cam, [[0.0, 0.0, 2.5]], CoverageConfig(step_m=0.5), bounds=(0, 20, 0, 0))
    assert cov.counts[0, 0] == 1 and cov.counts[0, -1] == 0
    assert np.all(np.isnan(cov.error_m))


def test_grid_size_is_bounded() -> None:
    cam = wide_angle_camera("pinhole")
    with pytest.raises(ValueError, match="max_points"):
        coverage_grid(cam, [[0, 0, 2.5]], CoverageConfig(step_m=0.01), bounds=(0, 100, 0, 100))


def test_spacing_flags_scale_with_ceiling_height() -> None:
    ids = [1, 2, 3, 4]
    pos = [[0.0, 0.0, 2.5], [0.2, 0.0, 2.5], [5.0, 0.0, 2.5], [6.0, 0.0, 2.5]]
    flags = spacing_flags(ids, pos)
    assert [(f.a, f.b, f.problem) for f in flags] == [(1, 2, "too_close")]
    np.testing.assert_allclose(flags[0].distance_m, 0.2)
    # 1.7 m is too far at 2.5 m but fine at 5 m (range 0.6-3.0 m)
    far = [[0.0, 0.0, 2.5], [1.7, 0.0, 2.5]]
    assert [f.problem for f in spacing_flags([7, 8], far)] == ["too_far"]
    high = [[0.0, 0.0, 5.0], [1.7, 0.0, 5.0]]
    assert spacing_flags([7, 8], high) == []
