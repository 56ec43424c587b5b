"""Symmetric banded matrices: the planning NLP's curvature model without its n x n zeros.

A grid node's quantities depend on the two points of its segment only, and the decision vector holds the
points' entries in order: the model's Hessian H couples entries of neighbouring points only. Its bandwidth b
(about two points' entries, 39 for the FPR) does not grow with the mission's length, so H is held as its
upper band, ``band[b - k, j] = H[j - k, j]`` for k = 0..b (LAPACK's upper banded storage, as
:func:`scipy.linalg.cholesky_banded` takes it): storing, adding, multiplying and factorising it cost
O(n b) and O(n b^2) instead of O(n^2) and O(n^3).

:class:`Banded` is what :class:`planners.problem.motion.MotionProblem` gives as ``Evaluation.hessian`` and what
the SQP's step QP (:mod:`planners.optimisation.active_set`) factorises. ``numpy.asarray`` of one is the dense
matrix (for callers that want it, and for tests).
"""

from __future__ import annotations

import numpy as np
from scipy import sparse
from scipy.linalg import cho_solve_banded, cholesky_banded


class Banded:
    """A symmetric n x n matrix held as its upper band (module docstring).

    Args:
        band: the upper band, shape (b + 1, n): ``band[b - k, j] = H[j - k, j]`` (entries with j < k unused, 0).
    """

    __array_priority__ = 20.0  # numpy's operators defer to this class's (``array @ banded``: :meth:`__rmatmul__`)

    def __init__(self, band: np.ndarray):
        self.band = np.asarray(band, dtype=float)
        if self.band.ndim != 2 or self.band.shape[0] < 1:
            raise ValueError(f"band.shape={self.band.shape}, expected (b + 1, n)")

    # ------------------------------------------------------------------ construction
    @classmethod
    def zeros(cls, n: int, bandwidth: int) -> Banded:
        """The n x n zero matrix with room for ``bandwidth`` off-diagonals."""
        return cls(np.zeros((bandwidth + 1, n)))

    @classmethod
    def from_dense(cls, matrix, bandwidth: int | None = None) -> Banded:
        """The band of a symmetric ``matrix`` (its upper triangle is read); ``bandwidth`` default: the largest
        offset of a non-zero.
        """
        a = np.asarray(matrix, dtype=float)
        n = a.shape[0]
        if bandwidth is None:
            rows, cols = np.nonzero(np.triu(a))
            bandwidth = int((cols - rows).max()) if rows.size else 0
        b = min(int(bandwidth), max(n - 1, 0))
        band = np.zeros((b + 1, n))
        for k in range(b + 1):
            band[b - k, k:] = np.diagonal(a, k)
        return cls(band)

    @staticmethod
    def flat_index(rows, cols, n: int, bandwidth: int) -> np.ndarray:
        """Where entry (rows, cols) of an n x n matrix sits in the flat band of ``bandwidth`` (rows <= cols,
        cols - rows <= bandwidth): what :meth:`scatter` adds at.
        """
        rows, cols = np.asarray(rows), np.asarray(cols)
        return (bandwidth - (cols - rows)) * n + cols

    @classmethod
    def scatter(cls, values, flat, n: int, bandwidth: int) -> Banded:
        """The matrix whose band is the sum of ``values`` at the flat band indices ``flat`` (:meth:`flat_index`)."""
        band = np.bincount(flat, values, minlength=(bandwidth + 1) * n)
        return cls(band.reshape(bandwidth + 1, n))

    # ------------------------------------------------------------------ properties
    @property
    def n(self) -> int:
        """The matrix's size."""
        return self.band.shape[1]

    @property
    def shape(self) -> tuple[int, int]:
        """(n, n)."""
        return self.n, self.n

    @property
    def bandwidth(self) -> int:
        """b: entries more than b off the diagonal are zero."""
        return self.band.shape[0] - 1

    def diagonal(self) -> np.ndarray:
        """The diagonal (n,) (a view)."""
        return self.band[-1]

    def abs_max(self) -> float:
        """max |H_ij| (0 for an empty matrix)."""
        return float(np.abs(self.band).max()) if self.band.size else 0.0

    def trace(self) -> float:
        """sum of the diagonal."""
        return float(self.diagonal().sum())

    def to_dense(self) -> np.ndarray:
        """The n x n array."""
        n, b = self.n, self.bandwidth
        out = np.zeros((n, n))
        for k in range(b + 1):
            diag = self.band[b - k, k:]
            idx = np.arange(n - k)
            out[idx, idx + k] = diag
            out[idx + k, idx] = diag
        return out

    def __array__(self, dtype=None, copy=None):
        dense = self.to_dense()
        return dense if dtype is None else dense.astype(dtype)

    def to_sparse_upper(self) -> sparse.csc_matrix:
        """The upper triangle as a CSC matrix (what ProxQP's sparse backend takes)."""
        n, b = self.n, self.bandwidth
        offsets = [k for k in range(b + 1) if k < n]
        return sparse.diags([self.band[b - k, k:] for k in offsets], offsets, shape=(n, n), format="csc")

    # ------------------------------------------------------------------ arithmetic
    def padded(self, b: int) -> np.ndarray:
        """The upper band padded to bandwidth ``b`` >= its own, (b + 1, n) (the band itself when b is its own)."""
        if b == self.bandwidth:
            return self.band
        out = np.zeros((b + 1, self.n))
        out[b - self.bandwidth:] = self.band
        return out

    def __add__(self, other) -> Banded:
        if isinstance(other, Banded):
            b = max(self.bandwidth, other.bandwidth)
            return Banded(self.padded(b) + other.padded(b))
        if np.isscalar(other) and other == 0:
            return self
        if isinstance(other, np.ndarray):
            return self.to_dense() + other
        return NotImplemented

    __radd__ = __add__

    def __mul__(self, factor):
        if np.isscalar(factor):
            return Banded(self.band * factor)
        if isinstance(factor, np.ndarray):  # elementwise with an array: the dense product
            return self.to_dense() * factor
        return NotImplemented

    __rmul__ = __mul__

    def shifted(self, shift: float) -> Banded:
        """H + shift I (a copy)."""
        band = self.band.copy()
        band[-1] += shift
        return Banded(band)

    def scaled_both(self, scale) -> Banded:
        """diag(scale) H diag(scale) (a copy)."""
        scale = np.asarray(scale, dtype=float)
        b, n = self.bandwidth, self.n
        band = self.band.copy()
        for k in range(b + 1):
            band[b - k, k:] *= scale[:n - k] * scale[k:]
        return Banded(band)

    def __matmul__(self, x):
        x = np.asarray(x, dtype=float)
        b, n = self.bandwidth, self.n
        out = self.band[b][(slice(None),) + (None,) * (x.ndim - 1)] * x
        for k in range(1, min(b, n - 1) + 1):
            diag = self.band[b - k, k:][(slice(None),) + (None,) * (x.ndim - 1)]
            out[:-k] += diag * x[k:]
            out[k:] += diag * x[:-k]
        return out

    def __rmatmul__(self, x):
        x = np.asarray(x, dtype=float)
        return (self @ x.T).T if x.ndim > 1 else self @ x

    def principal(self, index) -> Banded:
        """H[index][:, index] for increasing ``index`` (its bandwidth is at most this one's)."""
        index = np.asarray(index)
        m, b = index.size, self.bandwidth
        reduced = min(b, max(m - 1, 0))
        band = np.zeros((reduced + 1, m))
        for k in range(reduced + 1):
            i, j = index[:m - k], index[k:]
            offset = j - i
            inside = offset <= b
            values = np.zeros(m - k)
            values[inside] = self.band[b - offset[inside], j[inside]]
            band[reduced - k, k:] = values
        return Banded(band)

    def cholesky_solver(self, shift: float = 0.0):
        """The solve y -> (H + shift I)^-1 y by a banded Cholesky factorisation.

        Raises:
            numpy.linalg.LinAlgError: H + shift I is not positive definite (to round-off).
        """
        band = self.band
        if shift:
            band = band.copy()
            band[-1] += shift
        factor = cholesky_banded(band, lower=False, check_finite=False)
        return lambda y: cho_solve_banded((factor, False), y, check_finite=False)


__all__ = ["Banded"]
