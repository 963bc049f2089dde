"""Solves and inertia of an indefinite matrix from a Cholesky factor of it with a few diagonal entries raised.

Past a limit point a tangent ``K`` has one negative eigenvalue (a few past
several), and Cholesky fails on it. Raising the diagonal entries of a few
rows ``J`` by ``b > 0`` gives ``M = K + E B E^T`` (``E`` the columns of the
identity at ``J``, ``B = diag(b)``) on the same sparsity pattern; where ``M``
is positive definite, CHOLMOD factorises it with the analysis the path's
tangents already have, and ``K`` itself follows exactly:

* solves by the Woodbury identity,
  ``K^{-1} = M^{-1} + W S^{-1} W^T`` with ``W = M^{-1} E`` and the small
  matrix ``S = B^{-1} - E^T M^{-1} E``;
* the inertia by Haynsworth's additivity on ``[[M, E], [E^T, B^{-1}]]``:
  with ``M`` and ``B`` positive definite, ``K`` has exactly as many negative
  eigenvalues as ``S`` (Sylvester's law, like the pivots of ``L D L^T``).

``M`` is positive definite only if the rows raised carry enough of every
negative eigenvalue's mode: the caller chooses them (the continuation takes
the largest entries of the path tangent, along the critical mode next to a
limit point). On the 20-ring lattice dome past its limit point a factor took
3.0 ms against 7.3 ms for QDLDL's ``L D L^T``, at 16,131 unknowns 21 ms
against 90 ms (``benchmarks/results/bench_raised_cholesky.md``).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from .cholesky import CholeskyFactor
from .factor_base import SingularMatrixError, normwise_backward_error, refined_solve, row_sum_norm, shift_diagonal


class RaisedCholeskyFactor:
    """``K``'s solves and inertia from the Cholesky factor of ``K + E B E^T`` (see the module).

    Parameters
    ----------
    A : sparse matrix
        The symmetric matrix ``K`` (its whole diagonal stored).
    rows : sequence of int
        The rows ``J`` whose diagonal entries are raised.
    raise_by : float
        How much each is raised (``b``), relative to the largest diagonal
        entry of ``A`` in magnitude: twice it brings even a negative diagonal
        entry that large to a positive one. Larger values cost accuracy in
        ``S`` (it is ``1 / (1 + b (K^{-1})_jj)`` for one row ``j``: a
        cancellation of about ``b / |lambda|`` where ``lambda`` is the
        negative eigenvalue).
    previous : CholeskyFactor, optional
        A factor on the same pattern, whose analysis is reused (and storage
        taken over), as for :class:`CholeskyFactor`.
    check : float or None
        Largest accepted normwise backward error of a solve.
    refine : int
        Most steps of iterative refinement per solve.

    Raises
    ------
    NotPositiveDefiniteError
        When ``M`` is not positive definite (the rows raised were not enough).
    SingularMatrixError
        When ``S`` is singular: ``K`` is.
    """

    method = "raised-cholesky"

    def __init__(self, A, rows, raise_by: float = 2.0, previous: CholeskyFactor | None = None,
                 check: float | None = 1e-9, refine: int = 3):
        self.A = sp.csr_matrix(A)
        self.n = self.A.shape[0]
        self.rows = np.unique(np.asarray(rows, dtype=np.int64))
        if self.rows.size == 0 or self.rows[0] < 0 or self.rows[-1] >= self.n:
            raise ValueError(f"rows to raise must be within 0..{self.n - 1}, got {list(rows)}")
        diagonal = self.A.diagonal()
        self.scale = float(np.max(np.abs(diagonal))) if self.n else 1.0
        self.check, self.refine = check, int(refine)
        self._norm_inf = None
        b = float(raise_by) * self.scale
        shift = np.zeros(self.n)
        shift[self.rows] = b
        self.cholesky = CholeskyFactor(shift_diagonal(self.A, shift), previous=previous, stored=True)
        k = self.rows.size
        E = np.zeros((self.n, k))
        E[self.rows, np.arange(k)] = 1.0
        self._W = self.cholesky.solve(E).reshape(self.n, k)
        # S scaled by b (dimensionless, the identity when K = M): its eigenvalues are the pivots of
        # the bordered matrix relative to K's largest diagonal entry, like an LDL^T factor's pivot ratio
        S = np.eye(k) - b * self._W[self.rows, :]
        S = 0.5 * (S + S.T)
        self._s_eigenvalues = np.linalg.eigvalsh(S)
        if not np.all(np.isfinite(self._s_eigenvalues)) or np.any(self._s_eigenvalues == 0.0):
            raise SingularMatrixError("raised Cholesky: the matrix is singular (its capacitance matrix is)")
        self._S_inv_b = b * np.linalg.inv(S)  # (B^{-1} - E^T W)^{-1} = b S^{-1}

    # -- inertia -------------------------------------------------------------------
    @property
    def n_negative_pivots(self) -> int:
        """Negative eigenvalues of ``A``: those of ``S`` (``M`` positive definite)."""
        return int(np.count_nonzero(self._s_eigenvalues < 0.0))

    @property
    def inertia(self) -> tuple[int, int, int]:
        neg = self.n_negative_pivots
        return neg, 0, self.n - neg

    @property
    def min_pivot_ratio(self) -> float:
        """The smaller of ``M``'s smallest pivot and ``S``'s smallest eigenvalue, relative to ``A``'s diagonal."""
        chol = float(np.min(self.cholesky.pivots)) / self.scale if self.n else np.inf
        return min(chol, float(np.min(np.abs(self._s_eigenvalues))))

    @property
    def norm_inf(self) -> float:
        if self._norm_inf is None:
            self._norm_inf = row_sum_norm(self.A)
        return self._norm_inf

    @property
    def alive(self) -> bool:
        """Whether the factor can still solve (a later factorisation may have taken ``M``'s storage)."""
        return self.cholesky.alive

    # -- solves --------------------------------------------------------------------
    def _raw_solve(self, b: np.ndarray) -> np.ndarray:
        x = self.cholesky.solve(b)
        return x + self._W @ (self._S_inv_b @ x[self.rows])

    def solve(self, b: np.ndarray, refine: int | None = None) -> np.ndarray:
        """Solve ``A x = b`` with iterative refinement; raises SingularMatrixError on a poor backward error."""
        b = np.asarray(b, dtype=float)
        if b.ndim != 1:
            return np.column_stack([self.solve(b[:, j], refine) for j in range(b.shape[1])])
        x, eta = refined_solve(self.A, self._raw_solve, self.norm_inf, b, self.refine if refine is None else int(refine))
        if not np.all(np.isfinite(x)):
            raise SingularMatrixError("raised Cholesky solve produced non-finite values (matrix numerically singular)")
        if self.check is not None and eta > self.check:
            raise SingularMatrixError(
                f"raised Cholesky solve failed its backward-error check ({eta:.1e} > {self.check:.1e})")
        return x

    def backward_error(self) -> float:
        """Normwise backward error of an unrefined test solve with a random right-hand side."""
        rng = np.random.default_rng(12345)
        b = self.A @ rng.standard_normal(self.n)
        x = self._raw_solve(b)
        if not np.all(np.isfinite(x)):
            return np.inf
        return normwise_backward_error(self.norm_inf, x, b, b - self.A @ x)

    def trustworthy(self, pivot_tol: float = 1e-10, backward_tol: float = 1e-11) -> bool:
        """Whether the count of negative eigenvalues can be taken: no pivot near zero, small backward error."""
        return self.min_pivot_ratio > pivot_tol and self.backward_error() < backward_tol
