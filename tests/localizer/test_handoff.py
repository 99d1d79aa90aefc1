"""Hand-off: eq. (3) prediction with uncertainty, and map-geometry hypotheses."""

from __future__ import annotations

import math

import numpy as np
import pytest

from localizer.camera import T_body_camera_upward, predict_pixels
from localizer.geometry import T_world_body_from_pose
from localizer.handoff import (
    HandoffConfig,
    ceiling_points_body,
    consistent_hypotheses,
    hypothesis_pose,
    pose_from_ceiling_points,
    pose_mahalanobis2,
    position_sigma_m,
    predict_landmarks,
    visible_radius_m,
)
from sim.cameras import wide_angle_camera

CAM = wide_angle_camera(
    "pinhole", T_body_camera=T_body_camera_upward(yaw=math.pi / 2, offset_xy=(0.1, 0.0))
)
POS = np.array(
    [[0.0, 0.0, 2.5], [1.2, 0.0, 2.5], [0.6, 1.04, 2.45], [0.75, 0.1, 2.55], [9.0, 9.0, 2.5]]
)
POSE = (0.5, 0.3, 2.0)
SCALE = CAM.fu / 2.2


def _seen(pose=POSE, rows=(0, 1, 2)):
    px, valid = predict_pixels(CAM, T_world_body_from_pose(*pose), POS[list(rows)])
    assert valid.all()
    return px


def test_prediction_is_eq3_and_skips_far_landmarks() -> None:
    pred = predict_landmarks(
        CAM, POSE, np.zeros((3, 3)), POS, scale_px_per_m=SCALE, reach_m=visible_radius_m(CAM, 2.2)
    )
    assert 4 not in pred.rows.tolist()
    px, _ = predict_pixels(CAM, T_world_body_from_pose(*POSE), POS[pred.rows])
    np.testing.assert_allclose(pred.pixels, px)
    np.testing.assert_allclose(pred.sigma_px, 0.0)


def test_pixel_sigma_grows_with_position_and_heading_uncertainty() -> None:
    kw = {"scale_px_per_m": SCALE, "reach_m": 5.0, "candidates": np.array([0, 1])}
    a = predict_landmarks(CAM, POSE, np.diag([0.01**2, 0.01**2, 0.0]), POS, **kw)
    np.testing.assert_allclose(a.sigma_px, SCALE * 0.01)
    b = predict_landmarks(CAM, POSE, np.diag([0.01**2, 0.01**2, 0.01**2]), POS, **kw)
    assert np.all(b.sigma_px > a.sigma_px)


def test_ceiling_points_round_trip_to_the_pose() -> None:
    px = _seen()
    q = ceiling_points_body(CAM, px, POS[:3, 2])
    x, y, th = pose_from_ceiling_points(q, POS[:3, :2])
    np.testing.assert_allclose([x, y, th], POSE, atol=1e-6)


@pytest.mark.parametrize("theta", [math.pi - 1e-4, -math.pi + 1e-4])
def test_heading_near_pi(theta: float) -> None:
    pose = (0.6, 0.4, theta)
    px = _seen(pose)
    x, y, th = hypothesis_pose(CAM, POS, px, [(0, 0), (1, 1), (2, 2)])
    assert abs(math.remainder(th - theta, 2 * math.pi)) < 1e-6
    assert -math.pi < th <= math.pi
    assert pose_mahalanobis2((x, y, th), pose, np.eye(3) * 1e-4) < 1e-3


def _hyp_setup(extra: np.ndarray):
    px = np.vstack([_seen(), extra])
    pred = predict_landmarks(
        CAM, POSE, np.diag([0.2**2, 0.2**2, 0.05**2]), POS, scale_px_per_m=SCALE, reach_m=5.0,
        candidates=np.array([0, 1, 2]),
    )  # fmt: skip
    return px, pred


def test_glint_beside_a_landmark_gives_no_consistent_alternative() -> None:
    # A glint 20 cm beside landmark 1: within its (large) gate.
    glint = predict_pixels(CAM, T_world_body_from_pose(*POSE), [[1.2, 0.2, 2.5]])[0]
    px, pred = _hyp_setup(glint)
    hyps = consistent_hypotheses(CAM, pred, POS, px, np.full(3, 200.0), HandoffConfig())
    assert [(0, 0), (1, 1), (2, 2)] in hyps
    # Only the true spots make a full hypothesis (others are rotations of the triangle).
    assert all(3 not in [s for _, s in h] for h in hyps if len(h) == 3)


def test_swapped_landmarks_are_inconsistent() -> None:
    px = _seen(rows=(0, 1, 2))
    pred = predict_landmarks(
        CAM, POSE, np.zeros((3, 3)), POS, scale_px_per_m=SCALE, reach_m=5.0,
        candidates=np.array([0, 1, 2]),
    )  # fmt: skip
    # The three landmarks form an equilateral triangle: swapping two keeps every mutual
    # distance (a mirror image), which the rigid fit rejects; rotating all three is
    # consistent and only the prior pose tells it apart.
    hyps = consistent_hypotheses(CAM, pred, POS, px, np.full(3, 1000.0), HandoffConfig())
    full = [h for h in hyps if len(h) == 3]
    assert [(0, 0), (1, 1), (2, 2)] in full
    assert [(0, 2), (1, 1), (2, 0)] not in full
    prior = np.diag([0.1**2, 0.1**2, 0.1**2])
    passing = [
        h for h in full if pose_mahalanobis2(hypothesis_pose(CAM, POS, px, h), POSE, prior) < 16
    ]
    assert passing == [[(0, 0), (1, 1), (2, 2)]]


def test_no_hypothesis_with_fewer_than_two_candidates() -> None:
    px = _seen(rows=(0,))
    pred = predict_landmarks(
        CAM, POSE, np.zeros((3, 3)), POS, scale_px_per_m=SCALE, reach_m=5.0,
        candidates=np.array([0]),
    )  # fmt: skip
    assert consistent_hypotheses(CAM, pred, POS, px, np.full(1, 50.0), HandoffConfig()) == []


def test_mahalanobis_wraps_heading() -> None:
    d2 = pose_mahalanobis2((0.0, 0.0, math.pi - 0.01), (0.0, 0.0, -math.pi + 0.01), np.eye(3))
    assert d2 == pytest.approx(0.02**2)


def test_position_sigma_is_the_largest_eigenvalue() -> None:
    rng = np.random.default_rng(1)
    for _ in range(10):
        A = rng.normal(size=(3, 3))
        cov = A @ A.T
        expected = math.sqrt(np.linalg.eigvalsh(cov[:2, :2])[-1])
        assert position_sigma_m(cov) == pytest.approx(expected, rel=1e-12)
