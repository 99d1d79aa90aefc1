"""The calibration's consider term: a known answer, the pose error it must cover, and that it
does not shrink with the number of landmarks."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from localizer.calibration_consider import (
    CalibrationConsider,
    calibration_parameter_sigmas,
    consider_covariance,
)
from localizer.camera import CameraModel, predict_pixels
from localizer.geometry import T_world_body_from_pose
from localizer.pose import solve_pose
from tests.localizer.cameras import make_camera

POSE = (1.0, 2.0, 0.7)


def test_common_bias_does_not_average_out() -> None:
    # N readings of (x, y) with a common bias b (sigma_b) and independent noise sigma:
    # the mean's variance is sigma^2 / N + sigma_b^2
    n, sigma, sigma_b = 50, 0.5, 0.3
    J = np.tile(np.eye(2), (n, 1, 1))
    noise, cal = consider_covariance(J, np.full(n, sigma**-2), J.copy(), np.eye(2) * sigma_b**2)
    np.testing.assert_allclose(noise, np.eye(2) * sigma**2 / n)
    np.testing.assert_allclose(cal, np.eye(2) * sigma_b**2)
    # weighted by a wrong sigma, the noise part is still the estimator's true one
    noise_w, _ = consider_covariance(J, np.full(n, 4.0), J.copy(), np.eye(2), np.full(n, sigma**2))
    np.testing.assert_allclose(noise_w, np.eye(2) * sigma**2 / n)


def _ceiling(spacing: float) -> np.ndarray:
    xs = np.arange(-3.0, 3.0 + 1e-9, spacing)
    return np.array([[POSE[0] + a, POSE[1] + b, 2.7] for a in xs for b in xs])


def _perturbed(cam: CameraModel, k: int, step: float) -> CameraModel:
    """The camera with calibration parameter k (fu, fv, cu, cv, non-zero distortion) moved."""
    vals = [cam.fu, cam.fv, cam.cu, cam.cv]
    dist = cam.distortion.copy()
    if k < 4:
        vals[k] += step
    else:
        dist[np.flatnonzero(cam.distortion != 0.0)[k - 4]] += step
    fu, fv, cu, cv = vals
    return dataclasses.replace(cam, fu=fu, fv=fv, cu=cu, cv=cv, distortion=dist)


@pytest.mark.parametrize(
    ("lens", "mounting"), [("equidistant", "offset-yaw90"), ("radial-tangential", "offset-tilted")]
)
def test_covers_the_pose_error_a_calibration_error_causes(lens: str, mounting: str) -> None:
    cam = make_camera(lens, mounting)
    cc = CalibrationConsider.for_camera(cam, focal_rel=0.002, principal_px=0.6, distortion_rel=0.05)
    sigmas = calibration_parameter_sigmas(
        cam, focal_rel=0.002, principal_px=0.6, distortion_rel=0.05
    )
    np.testing.assert_allclose(cc.sigmas, sigmas)
    assert len(sigmas) == 4 + int(np.sum(cam.distortion != 0.0))
    T = T_world_body_from_pose(*POSE)
    stds = {}
    for spacing in (0.8, 0.4):
        P = _ceiling(spacing)
        px, ok = predict_pixels(cam, T, P)
        P, px = P[ok], px[ok]
        # The truth is the calibration moved by one sigma of each parameter in turn; the
        # localizer solves with the nominal one. To first order the pose errors e_k are the
        # columns of A Sigma_cal^(1/2), so sum_k e_k e_k^T is the consider term.
        # (Solved with a tiny sigma: the solver stops at a fraction of a sigma.)
        outer = np.zeros((3, 3))
        for k, step in enumerate(sigmas):
            z, seen = predict_pixels(_perturbed(cam, k, float(step)), T, P)
            fix = solve_pose(cam, z[seen], P[seen], initial=POSE, pixel_sigma_px=0.01)
            assert fix is not None
            e = np.array([fix.x, fix.y, fix.theta]) - POSE
            outer += np.outer(e, e)
        parts = cc.covariance(px, P, POSE, np.full(len(px), 0.5))
        assert parts is not None
        noise, cal = parts
        np.testing.assert_allclose(np.sqrt(np.diag(cal)), np.sqrt(np.diag(outer)), rtol=0.15)
        # the pose error is centimetres' worth of the calibration, the noise part millimetres
        assert np.sqrt(cal[0, 0]) > 5 * np.sqrt(noise[0, 0])
        stds[spacing] = (np.sqrt(np.diag(noise)), np.sqrt(np.diag(cal)), len(P))
    (n_sparse, c_sparse, m_sparse), (n_dense, c_dense, m_dense) = stds[0.8], stds[0.4]
    assert m_dense > 3.5 * m_sparse
    # four times the landmarks: the noise part halves, the calibration's position part does
    # not shrink (its heading part is under 0.03 deg either way on a symmetric grid)
    np.testing.assert_allclose(n_dense, n_sparse / 2, rtol=0.15)
    np.testing.assert_allclose(c_dense[:2], c_sparse[:2], rtol=0.1)
    assert c_dense[2] < 5e-4 and c_sparse[2] < 5e-4


def test_degenerate_geometry_is_none() -> None:
    cam = make_camera("equidistant", "upward")
    cc = CalibrationConsider.for_camera(cam, focal_rel=0.002, principal_px=0.6, distortion_rel=0.05)
    one = cc.covariance([[300.0, 200.0]], [[1.0, 2.0, 2.7]], POSE, [0.5])
    below = cc.covariance([[300.0, 200.0], [340.0, 200.0]], [[1, 2, -1.0], [1.2, 2, -1.0]],
                          POSE, [0.5, 0.5])  # fmt: skip
    assert one is None and below is None
