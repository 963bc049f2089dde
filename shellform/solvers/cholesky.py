"""Supernodal Cholesky (CHOLMOD through cvxopt) for symmetric positive definite matrices."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from .factor_base import NotPositiveDefiniteError, SingularMatrixError


#: Largest share of exact zeros a :class:`CholeskyFactor` keeps in its analysis.
#: On a 100 x 100 rope net with 13 % of the tangent's entries zero (slack
#: ropes), one numeric factorisation took 11 ms without them against 20 ms
#: with them, and a new analysis costs 8 ms; at 316 x 316, 0.15 s against
#: 0.53 s, and 0.14 s. Over the first 40 factorisations of a relaxation of
#: the 316 x 316 net (analysis + numeric): 21.6 s with every stored entry,
#: 11.3 s analysing only the nonzeros every time, 13.3 s with this 5 % rule;
#: over a whole relaxation of the 100 x 100 net 1.58 s, 1.39 s and 1.23 s
#: (the analysis is redone 43 times instead of 71).
ZERO_SHARE = 0.05


def _zero_share(analysed: np.ndarray, needed: np.ndarray) -> float:
    """Share of the analysed entries that are not needed (exact zeros)."""
    n = np.count_nonzero(analysed)
    return np.count_nonzero(analysed & ~needed) / n if n else 0.0


class CholeskyFactor:
    """Supernodal sparse Cholesky ``A = L L^T`` (CHOLMOD) for symmetric positive definite matrices.

    CHOLMOD (SuiteSparse, through cvxopt's binding) orders by approximate
    minimum degree like QDLDL but factorises dense supernodes with BLAS:
    on the tangent of a taut 316 x 316 rope net (295,788 unknowns) one
    numeric refactorisation took 0.63 s against QDLDL's 9.6 s, and 0.022 s
    against 0.11 s at 100 x 100 (``benchmarks/results/bench_factorization.md``).
    Its time grows about as the number of unknowns to the power 1.45 on
    these surface-like graphs (17.6 s at 1000 x 1000 nodes, 12 GB), in a
    nested-dissection order as well. It has no inertia: use
    :class:`LDLFactor` where the matrix may be indefinite.

    Parameters
    ----------
    A : sparse matrix
        Symmetric positive definite (its upper triangle is used).
    previous : CholeskyFactor, optional
        A factor of a matrix with the same nonzero entries (exact zeros are
        left out): its ordering and symbolic analysis are reused and its
        storage is taken over (it cannot solve afterwards).
    stored : bool
        Analyse every stored entry while no more than ``ZERO_SHARE`` of them
        are zero. For tangents whose exact zeros are incidental (a bar's
        direction along an axis, a symmetric state) and change from one
        state to the next: on the 20-ring lattice dome 16 of 19 analyses
        along a path were redone for entries that had become nonzero.

    Raises
    ------
    NotPositiveDefiniteError
        When ``A`` is not (numerically) positive definite.
    """

    method = "cholesky"

    def __init__(self, A, previous: CholeskyFactor | None = None, stored: bool = False):
        from cvxopt import cholmod, matrix, spmatrix

        A = sp.csr_matrix(A)
        same_pattern = (previous is not None and previous._symbolic is not None
                        and np.array_equal(previous._indptr, A.indptr) and np.array_equal(previous._indices, A.indices))
        # the previous matrix's pattern was canonical, and so is the same one (0.05 ms a check at n = 5)
        if not same_pattern and not A.has_canonical_format:
            A = A.copy()
            A.sum_duplicates()
        self.shape = A.shape
        n = A.shape[0]
        if same_pattern:
            # the stored pattern's rows and triangle were worked out (and checked) with the previous matrix
            row, on_diagonal, lower = previous._row, previous._on_diagonal, previous._lower
        else:
            row = np.repeat(np.arange(n), np.diff(A.indptr))
            on_diagonal = A.indices == row
            if np.count_nonzero(on_diagonal) < n:
                missing = np.setdiff1d(np.arange(n), row[on_diagonal])
                raise SingularMatrixError(
                    f"Cholesky factorisation: row {int(missing[0])} has no diagonal entry "
                    f"({missing.size} such rows): the matrix is not positive definite")
            lower = A.indices <= row
        self._indptr, self._indices = (previous._indptr, previous._indices) if same_pattern else (
            A.indptr.copy(), A.indices.copy())
        self._row, self._on_diagonal, self._lower = row, on_diagonal, lower
        # Exact zeros are left out of the analysis: a slack rope's block of a
        # tangent is exactly zero, and analysed as if the rope were taut it
        # fills the factor all the same (see ZERO_SHARE).
        needed = lower & ((A.data != 0.0) | on_diagonal)
        self._stale = False
        reused = False
        if same_pattern and not np.any(needed & ~previous._analysed) and _zero_share(previous._analysed, needed) <= ZERO_SHARE:
            reused = True
            # the previous analysis covers these nonzeros: reuse it and take over its storage
            self._M, self._symbolic = previous._M, previous._symbolic
            self._analysed, self._keep = previous._analysed, previous._keep
            previous._symbolic = None
            self._M.V = matrix(A.data[self._keep])
        else:
            # entries that were nonzero a moment ago are likely to be again (a rope going slack
            # and taut): keep them in the new analysis while they are few
            analysed = needed | previous._analysed if same_pattern else needed
            if stored and _zero_share(lower, needed) <= ZERO_SHARE:
                analysed = lower  # every stored entry, so that no incidental zero calls for a new analysis
            if _zero_share(analysed, needed) > ZERO_SHARE:
                analysed = needed
            keep = np.flatnonzero(analysed)
            # the lower triangle of the CSR arrays is the upper triangle in CSC order (A is symmetric)
            self._M = spmatrix(matrix(A.data[keep]), matrix(A.indices[keep].astype(np.int64)),
                               matrix(row[keep].astype(np.int64)), A.shape)
            self._symbolic = cholmod.symbolic(self._M, uplo="U")
            self._analysed, self._keep = analysed, keep
        try:
            cholmod.numeric(self._M, self._symbolic)
        except ArithmeticError as exc:
            # CHOLMOD reports the column where a pivot was not positive. A reused analysis goes
            # back to the factor it came from, whose values it no longer holds, so that the next
            # factorisation of the pattern still reuses it (past a critical point Cholesky fails
            # at every other trial point of an event's location)
            if reused:
                previous._M, previous._symbolic = self._M, self._symbolic
                previous._stale = True
            self._symbolic = None
            raise NotPositiveDefiniteError(
                f"Cholesky factorisation failed (pivot {exc} of the reordered matrix is not positive): "
                "the matrix is not positive definite"
            ) from None

    @property
    def alive(self) -> bool:
        """Whether the factor can still solve (a later factorisation may have taken its storage)."""
        return self._symbolic is not None and not self._stale

    @property
    def pivots(self) -> np.ndarray:
        """The squares of the diagonal of ``L``: the pivots of ``A = L D L^T`` in the factor's ordering."""
        from cvxopt import cholmod

        if not self.alive:
            raise SingularMatrixError("this Cholesky factor's storage was reused by a later factorisation")
        return np.array(cholmod.diag(self._symbolic)).ravel() ** 2

    def solve(self, b: np.ndarray) -> np.ndarray:
        """``A^{-1} b`` for one right-hand side or one per column."""
        from cvxopt import cholmod, matrix

        if self._symbolic is None or self._stale:
            raise SingularMatrixError("this Cholesky factor's storage was reused by a later factorisation")
        b = np.asarray(b, dtype=float)
        B = matrix(b.reshape(b.shape[0], -1))
        cholmod.solve(self._symbolic, B)
        x = np.array(B).reshape(b.shape)
        if not np.all(np.isfinite(x)):
            raise SingularMatrixError("Cholesky solve produced non-finite values (matrix numerically singular)")
        return x
