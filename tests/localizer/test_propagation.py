"""The batched covariance propagation equals the step-by-step EKF propagation."""

from __future__ import annotations

import numpy as np

from localizer.calibrated_odometry import jacob_f, motion_model
from localizer.propagation import DeferredPropagation

W = 0.36


def _batch(walk: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(P before, step by step with numpy (the walk left out), the batch's result)."""
    rng = np.random.default_rng(5)
    A = rng.normal(size=(6, 6))
    P0 = A @ A.T * 1e-4  # a full covariance: pose-calibration correlations too
    X = [0.3, -0.2, 2.9, 1.01, 0.99, 1.02]
    prop = DeferredPropagation()
    P = P0.copy()
    for vl, vr in rng.uniform(-0.5, 0.8, (25, 2)):
        F_top, G = jacob_f(X, vl, vr, 0.01, W)
        m = rng.uniform(1e-6, 1e-5, 2)
        F = np.vstack([F_top, np.hstack([np.zeros((3, 3)), np.eye(3)])])
        Gf = np.vstack([G, np.zeros((3, 2))])
        P = F @ P @ F.T + Gf @ np.diag(m) @ Gf.T
        prop.add_step(F_top, G, float(m[0]), float(m[1]), walk)
        X = motion_model(X, vl, vr, 0.01, W)
    assert prop.pending
    got = np.array(prop.apply(P0.tolist()))
    assert not prop.pending
    return P0, P, got


def test_batch_equals_step_by_step() -> None:
    _, P, got = _batch(walk=0.0)
    np.testing.assert_allclose(got, P, rtol=1e-9, atol=1e-16)
    np.testing.assert_allclose(got, got.T, rtol=1e-12, atol=0)


def test_walk_is_added_to_the_calibration_diagonal_once_per_batch() -> None:
    _, _, without = _batch(walk=0.0)
    _, _, with_walk = _batch(walk=1e-9)
    np.testing.assert_allclose(with_walk - without, np.diag([0, 0, 0, 25e-9, 25e-9, 25e-9]))


def test_an_empty_batch_is_the_identity() -> None:
    P0, _, _ = _batch(walk=0.0)
    np.testing.assert_allclose(DeferredPropagation().apply(P0.tolist()), P0, rtol=0, atol=0)


def test_carry_is_the_composed_jacobian_times_c() -> None:
    """`carry` (written out on floats) against F_n ... F_1 C on numpy."""
    rng = np.random.default_rng(6)
    C = rng.normal(0.0, 1e-3, (6, 3))
    X = [0.3, -0.2, 2.9, 1.01, 0.99, 1.02]
    prop, Phi = DeferredPropagation(), np.eye(6)
    for vl, vr in rng.uniform(-0.5, 0.8, (25, 2)):
        F_top, G = jacob_f(X, vl, vr, 0.01, W)
        Phi = np.vstack([F_top, np.hstack([np.zeros((3, 3)), np.eye(3)])]) @ Phi
        prop.add_step(F_top, G, 1e-6, 1e-6, 0.0)
        X = motion_model(X, vl, vr, 0.01, W)
    np.testing.assert_allclose(prop.carry(C.tolist()), Phi @ C, rtol=1e-9, atol=1e-16)
    assert prop.pending  # (apply follows)
