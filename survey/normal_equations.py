"""The survey's normal equations, solved the way bundle adjusters do: by a Schur complement.

The unknowns split into a long banded block (the keyframe poses: each pose meets only its
two neighbours, through the wheels' intervals, so its block of the normal matrix is banded
with a half-bandwidth of 5) and a short dense rest (the landmarks, the wheels' calibration,
the camera's correction). The banded block is factored by a banded Cholesky
(`scipy.linalg.cholesky_banded`, linear in the drive's length), the rest by a dense Cholesky
of its Schur complement

    S = H_rr - H_rp H_pp^-1 H_pr,

whose inverse is exactly the marginal covariance of the rest with the poses eliminated
(`reduced_covariance`). A general sparse LU (`splu`) of the whole matrix fills in along the
camera's columns, which every spot touches, and grew to seconds a step on a long drive.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
import scipy.sparse as sp
from scipy.linalg import cho_factor, cho_solve, cho_solve_banded, cholesky_banded

from localizer.types import FloatArray


class BandedSchur:
    """A factorisation of a symmetric positive definite matrix H whose leading `n_banded`
    unknowns form a banded block.

    Raises:
        numpy.linalg.LinAlgError: H is not positive definite (damp it more).
    """

    def __init__(self, H: sp.spmatrix, n_banded: int) -> None:
        Hc = sp.csr_matrix(H)
        n = n_banded
        self.n_banded = n
        Hpp = Hc[:n, :n].tocoo()
        upper = Hpp.col >= Hpp.row
        i, j, v = Hpp.row[upper], Hpp.col[upper], Hpp.data[upper]
        u = int(np.max(j - i)) if len(i) else 0
        ab = np.zeros((u + 1, n))
        np.add.at(ab, (u + i - j, j), v)
        self._band = cholesky_banded(ab, lower=False)
        self._Hpr = Hc[:n, n:].toarray()
        Hrr = Hc[n:, n:].toarray()
        self._Y = self._solve_banded(self._Hpr)  # H_pp^-1 H_pr
        S = Hrr - self._Hpr.T @ self._Y
        self.schur: FloatArray = 0.5 * (S + S.T)
        self._S = cho_factor(self.schur, lower=False)

    def _solve_banded(self, b: FloatArray) -> FloatArray:
        if self.n_banded == 0:
            return np.zeros_like(b)
        out: FloatArray = cho_solve_banded((self._band, False), b)
        return out

    def solve(self, b: FloatArray) -> FloatArray:
        """x with H x = b."""
        n = self.n_banded
        bp, br = b[:n], b[n:]
        z = self._solve_banded(bp)
        xr = cho_solve(self._S, br - self._Hpr.T @ z)
        xp = z - self._Y @ xr
        return np.concatenate([xp, xr])

    def reduced_rhs(self, b: FloatArray) -> FloatArray:
        """b_r - H_rp H_pp^-1 b_p: a right-hand side (a gradient) with the banded unknowns
        eliminated, as the Schur complement eliminates them from H."""
        n = self.n_banded
        out: FloatArray = b[n:] - self._Y.T @ b[:n]
        return out

    def reduced_covariance(self) -> FloatArray:
        """The inverse of H restricted to the unknowns after the banded block: their marginal
        covariance (for H an information matrix), shape (n - n_banded, n - n_banded)."""
        eye = np.eye(len(self.schur))
        cov: FloatArray = cho_solve(self._S, eye)
        return 0.5 * (cov + cov.T)

    def banded_covariance_blocks(self, blocks: npt.ArrayLike, size: int = 3) -> FloatArray:
        """Diagonal blocks of H^-1 within the banded unknowns: for each block index b, the
        marginal covariance of unknowns [size b, size (b + 1)) (a keyframe pose), the rest
        eliminated: H_pp^-1 + Y S^-1 Y^T restricted to it (Y = H_pp^-1 H_pr), shape
        (B, size, size)."""
        idx = np.asarray(blocks, dtype=np.int64).reshape(-1)
        if len(idx) == 0:
            return np.zeros((0, size, size))
        cols = (size * idx[:, None] + np.arange(size)[None, :]).reshape(-1)
        E = np.zeros((self.n_banded, len(cols)))
        E[cols, np.arange(len(cols))] = 1.0
        Z = self._solve_banded(E)[cols]  # rows and columns of H_pp^-1 at `cols`
        Yc = self._Y[cols]
        full = Z + Yc @ cho_solve(self._S, Yc.T)
        out = np.empty((len(idx), size, size))
        for b in range(len(idx)):
            blk = full[size * b : size * b + size, size * b : size * b + size]
            out[b] = 0.5 * (blk + blk.T)
        return out
