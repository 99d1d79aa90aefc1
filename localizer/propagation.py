"""The pose filter's covariance propagation over a batch of odometry steps, applied at once.

Odometry arrives at 50-200 Hz, several samples per frame, and the covariance is needed only
at the next fix (or read). So each step's Jacobians are folded in as they come and
P <- F P F^T + G M G^T is applied once for the whole batch:

    Phi <- F Phi                      (Phi = F_n ... F_1),
    Q   <- A Q A^T + G M G^T          (A: the pose block of F; the pose noise so far),
    P   <- [[Phi], [0 I]] P [[Phi], [0 I]]^T + Q (pose block) + walk (calibration diagonal).

This is the step-by-step propagation regrouped, not an approximation: F's calibration rows
are [0 I] and G acts on the pose only, so the pose noise of earlier steps is carried by the
later steps' pose blocks A alone, and Phi P Phi^T + Q equals the n sequential updates (up to
rounding; `tests/localizer/test_pose_filter.py` checks it against numpy step by step). Only
the calibration random walk is added at the end of the batch (its propagation into the
pose within one batch, a second-order effect, is dropped).

State X = (x, y, theta, k_r, k_l, k_b); everything on Python floats (a 6x6 covariance as
nested lists): for this size numpy's per-call overhead costs more than the arithmetic.
"""

from __future__ import annotations

Vec3 = tuple[float, float, float]
Rows = list[list[float]]
_ZERO3: Vec3 = (0.0, 0.0, 0.0)


class DeferredPropagation:
    """Composed Jacobian and accumulated noise of the odometry steps since the last `apply`.

    F's pose block has the form [[1, 0, a], [0, 1, b], [0, 0, 1]] (eq. 5), and so has a
    product of such blocks: Phi's pose rows are kept as (a, b) and the 3x3 block B on the
    calibration columns, Phi = [[1, 0, a, B0], [0, 1, b, B1], [0, 0, 1, B2]].
    """

    def __init__(self) -> None:
        self.clear()

    def clear(self) -> None:
        """Start a new batch (Phi = I, Q = 0)."""
        self._a = self._b = 0.0
        self._B: tuple[Vec3, Vec3, Vec3] = (_ZERO3, _ZERO3, _ZERO3)
        self._Q: tuple[float, ...] = (0.0,) * 6  # pose noise, upper triangle row by row
        self._walk = 0.0
        self.pending = False

    def copy(self) -> DeferredPropagation:
        """An independent copy of the batch (its parts are immutable: a shallow copy)."""
        twin = object.__new__(DeferredPropagation)
        twin.__dict__.update(self.__dict__)
        return twin

    def add_step(self, F_top: Rows, G: Rows, m_left: float, m_right: float, walk: float) -> None:
        """Fold in one step.

        Args:
            F_top: the pose rows of F = df/dX, 3 x 6 (`calibrated_odometry.jacob_f`).
            G: d pose / d (true left, right wheel speeds), 3 x 2.
            m_left, m_right: variances of the true wheel speeds over the step, (m/s)^2.
            walk: variance added to each calibration factor over the step.
        """
        (_, _, a, f03, f04, f05), (_, _, b, f13, f14, f15), (_, _, _, f23, f24, f25) = F_top
        B0, B1, (c0, c1, c2) = self._B
        self._a += a
        self._b += b
        self._B = (  # (written out: for 3-vectors a comprehension costs more than its work)
            (B0[0] + a * c0 + f03, B0[1] + a * c1 + f04, B0[2] + a * c2 + f05),
            (B1[0] + b * c0 + f13, B1[1] + b * c1 + f14, B1[2] + b * c2 + f15),
            (c0 + f23, c1 + f24, c2 + f25),
        )
        q00, q01, q02, q11, q12, q22 = self._Q
        t00, t01, t02 = q00 + a * q02, q01 + a * q12, q02 + a * q22
        t11, t12 = q11 + b * q12, q12 + b * q22
        (l0, r0), (l1, r1), (l2, r2) = G
        self._Q = (
            t00 + a * t02 + m_left * l0 * l0 + m_right * r0 * r0,
            t01 + b * t02 + m_left * l0 * l1 + m_right * r0 * r1,
            t02 + m_left * l0 * l2 + m_right * r0 * r2,
            t11 + b * t12 + m_left * l1 * l1 + m_right * r1 * r1,
            t12 + m_left * l1 * l2 + m_right * r1 * r2,
            q22 + m_left * l2 * l2 + m_right * r2 * r2,
        )
        self._walk += walk
        self.pending = True

    def carry(self, C: Rows) -> Rows:
        """Phi C for a matrix of the state's rows (6 x 3 nested lists; e.g. the
        cross-covariance of the state's error with something the odometry does not move,
        `fix_bias`); the batch stays pending (`apply` follows)."""
        a, b = self._a, self._b
        (e00, e01, e02), (e10, e11, e12), (e20, e21, e22) = self._B
        (u0, u1, u2), (v0, v1, v2), (w0, w1, w2), C3, C4, C5 = C
        (p0, p1, p2), (q0, q1, q2), (r0, r1, r2) = C3, C4, C5
        # (written out: the consider update carries C on every frame)
        return [
            [
                u0 + a * w0 + e00 * p0 + e01 * q0 + e02 * r0,
                u1 + a * w1 + e00 * p1 + e01 * q1 + e02 * r1,
                u2 + a * w2 + e00 * p2 + e01 * q2 + e02 * r2,
            ],
            [
                v0 + b * w0 + e10 * p0 + e11 * q0 + e12 * r0,
                v1 + b * w1 + e10 * p1 + e11 * q1 + e12 * r1,
                v2 + b * w2 + e10 * p2 + e11 * q2 + e12 * r2,
            ],
            [
                w0 + e20 * p0 + e21 * q0 + e22 * r0,
                w1 + e20 * p1 + e21 * q1 + e22 * r1,
                w2 + e20 * p2 + e21 * q2 + e22 * r2,
            ],
            C3,
            C4,
            C5,
        ]

    def apply(self, P: Rows) -> Rows:
        """The propagated covariance (6 x 6 nested lists) of `P`; clears the batch.

        With M = Phi P (the pose rows of F P): P_pose = M Phi^T + Q, P_pose,cal = M[:, 3:],
        P_cal unchanged but for the walk.
        """
        a, b, (B0, B1, B2) = self._a, self._b, self._B
        P0, P1, P2, P3, P4, P5 = P
        q00, q01, q02, q11, q12, q22 = self._Q
        top = []
        for Pi, c, (d0, d1, d2), (q0, q1, q2) in (
            (P0, a, B0, (q00, q01, q02)),
            (P1, b, B1, (q01, q11, q12)),
            (P2, 0.0, B2, (q02, q12, q22)),
        ):
            m0, m1, m2, m3, m4, m5 = [  # row i of M
                u + c * w + d0 * p + d1 * q + d2 * r
                for u, w, p, q, r in zip(Pi, P2, P3, P4, P5, strict=True)
            ]
            x0 = m0 + a * m2 + m3 * B0[0] + m4 * B0[1] + m5 * B0[2]  # row i of M Phi^T
            x1 = m1 + b * m2 + m3 * B1[0] + m4 * B1[1] + m5 * B1[2]
            x2 = m2 + m3 * B2[0] + m4 * B2[1] + m5 * B2[2]
            top.append([x0 + q0, x1 + q1, x2 + q2, m3, m4, m5])
        (_, _, _, t03, t04, t05), (_, _, _, t13, t14, t15), (_, _, _, t23, t24, t25) = top
        w = self._walk
        self.clear()
        return [
            *top,
            [t03, t13, t23, P3[3] + w, P3[4], P3[5]],
            [t04, t14, t24, P4[3], P4[4] + w, P4[5]],
            [t05, t15, t25, P5[3], P5[4], P5[5] + w],
        ]
