"""Sparse LDL^T (QDLDL) with its inertia, and the symbolic analyses kept for the next matrix of a pattern."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..sparse_pattern import same_pattern
from .factor_base import SingularMatrixError, normwise_backward_error, refined_solve, row_sum_norm, upper_csc


class _SymbolicPool:
    """qdldl solvers that no factor holds any more, kept by sparsity pattern.

    A qdldl solver keeps the AMD ordering and the symbolic factorisation of
    its pattern; a refactorisation of new values on the same pattern
    (``update``) skips both. On the n = 11 hemisphere's tangent (7,628
    unknowns) a fresh factorisation takes 9.6 ms and an update 2.1 ms; on
    the n = 5 one (3,688) 1.8 ms and 0.5 ms. An :class:`LDLFactor` gives its
    solver back here when it is freed, and a new factor of a matrix with the
    same pattern takes it, so that one analysis per pattern serves a whole
    run: the Newton solves, the stability counts, the shifted
    factorisations of the eigenvalue solves, implicit Euler's steps.
    """

    #: patterns kept at most, one solver each (each holds one factor's storage)
    size = 4

    def __init__(self):
        self._items: list[tuple[np.ndarray, np.ndarray, object]] = []

    def take(self, U: sp.csc_matrix):
        for k, (indptr, indices, solver) in enumerate(self._items):
            if same_pattern((indptr, indices), (U.indptr, U.indices)):
                del self._items[k]
                return solver
        return None

    def give(self, U: sp.csc_matrix, solver) -> None:
        # one analysis per pattern is all a later factor needs: a second one is not kept
        self.take(U)
        self._items.insert(0, (U.indptr, U.indices, solver))
        del self._items[self.size:]

    def clear(self) -> None:
        self._items.clear()


_POOL = _SymbolicPool()


class _PatternCosts:
    """QDLDL's cost of a numeric factorisation (multiply-adds), by sparsity pattern, for the patterns met last.

    The sum over the columns of its ``L`` of ``c (c + 1)``, ``c`` the column's
    count (:func:`_pattern_cost`), so that the ``auto`` backend can send a
    pattern with much fill to PARDISO (:func:`~shellform.solvers.pardiso.use_pardiso`).
    """

    size = 8

    def __init__(self):
        self._items: list[tuple[np.ndarray, np.ndarray, float]] = []

    def get(self, U: sp.csc_matrix) -> float | None:
        for indptr, indices, cost in self._items:
            if same_pattern((indptr, indices), (U.indptr, U.indices)):
                return cost
        return None

    def put(self, U: sp.csc_matrix, cost: float) -> None:
        self._items.insert(0, (U.indptr.copy(), U.indices.copy(), float(cost)))
        del self._items[self.size:]


_COSTS = _PatternCosts()


def _pattern_cost(U: sp.csc_matrix) -> float | None:
    """QDLDL's multiply-adds for the pattern of ``U`` (None where it meets a zero pivot).

    Measured once per pattern, before any factor of it is used, so that every
    factorisation of a pattern goes to the same backend whatever came before
    it in the process (the same answers to the last bit). The solver made to
    measure it goes to the pool: its analysis serves the pattern's QDLDL factors.
    """
    import qdldl

    cost = _COSTS.get(U)
    if cost is None:
        try:
            solver = qdldl.Solver(U, upper=True)
        except (RuntimeError, ValueError):
            return None
        counts = np.diff(sp.csc_matrix(solver.factors()[0]).indptr).astype(float)
        cost = float(np.sum(counts * (counts + 1.0)))
        _COSTS.put(U, cost)
        _POOL.give(U, solver)
    return cost


def _refactorise(solver, U: sp.csc_matrix):
    """New values into a qdldl solver's kept analysis (the analysis goes back to the pool on failure).

    ``update`` stops at a zero pivot without saying so, the rest of the
    factor left from the previous matrix: the pivots' check when they are
    read (:attr:`LDLFactor.d`) and every solve's backward-error check find
    it. Reading the pivots at once would cost their whole ``L`` (1.5-2 ms at
    3.7k unknowns on the lattice dome's tangent, a quarter of the numeric
    factorisation), which the corrector's solves past a limit point never need.
    """
    try:
        solver.update(U, upper=True)
    except (RuntimeError, ValueError) as exc:
        _POOL.give(U, solver)
        raise SingularMatrixError(f"LDL^T factorisation failed: {exc}") from None
    return solver


class LDLFactor:
    """Sparse ``L D L^T`` of a symmetric matrix (QDLDL, AMD ordering, no pivoting).

    One factor serves solves (Newton, continuation, shift-invert Lanczos) and
    stability: by Sylvester's law ``A`` has as many negative eigenvalues as
    ``D`` has negative entries. Without pivoting a factorisation of an
    indefinite matrix can meet a tiny pivot or grow large entries, so

    * a non-finite entry of ``A`` raises :class:`SingularMatrixError`, and
      so does a zero or non-finite pivot: in the constructor for a fresh
      analysis, otherwise when the pivots ``d`` are read (only for the
      inertia) or by the solves' check below;
    * every solve is refined iteratively and raises when its normwise backward
      error ``|A x - b| / (|A| |x| + |b|)`` (infinity norms) stays above
      ``check``. This measure, unlike a residual relative to ``|b|`` alone,
      accepts the large but accurate solutions next to a critical point,
      where ``A`` is nearly singular;
    * :meth:`trustworthy` tells whether the pivot signs may be taken as the
      inertia (no tiny pivot, small backward error of a test solve).

    Parameters
    ----------
    A : sparse matrix
        Symmetric matrix; only its lower triangle in CSR order is read.
    previous : LDLFactor, optional
        A factor of a matrix with the same sparsity pattern; its ordering and
        symbolic factorisation are reused (qdldl ``update``). ``previous``
        gives its storage to the new factor and cannot solve any more.
        Without it, the analysis of a freed factor of the same pattern is
        reused when there is one (:class:`_SymbolicPool`); the factor is the
        same either way.
    check : float or None
        Largest accepted backward error of a solve (None: no check).
    refine : int
        Most steps of iterative refinement per solve.
    backend : {"auto", "qdldl", "pardiso"}, optional
        Who factorises: QDLDL, or MKL PARDISO (supernodal, 1x1 pivoting,
        where its inertia can be trusted; see :mod:`shellform.solvers.pardiso`).
        None: the ``SHELLFORM_LDL`` environment variable, ``auto`` when unset.

    Raises
    ------
    SingularMatrixError
        When ``A`` has a non-finite entry, or a fresh analysis meets a zero pivot.
    """

    method = "ldl"

    def __init__(self, A, previous: LDLFactor | None = None, check: float | None = 1e-9, refine: int = 3,
                 backend: str | None = None):
        import qdldl

        from . import pardiso

        U = upper_csc(A)
        if not np.all(np.isfinite(U.data)):
            bad = int(np.flatnonzero(~np.isfinite(U.data))[0])
            col = int(np.searchsorted(U.indptr, bad, side="right") - 1)
            raise SingularMatrixError(
                f"LDL^T factorisation: the matrix has a non-finite entry (row {int(U.indices[bad])}, column {col})")
        self.A = sp.csr_matrix(A)
        self.n = U.shape[0]
        self.check = check
        self.refine = int(refine)
        self.scale = float(np.max(np.abs(U.diagonal()))) if self.n else 0.0
        if self.scale == 0.0:
            self.scale = float(np.max(np.abs(U.data))) if U.nnz else 1.0
        self._solver = None
        self._norm_inf = None
        self.backend = "qdldl"
        if pardiso.use_pardiso(self.n, backend, lambda: _pattern_cost(U)):
            solver = pardiso.factor(U, previous)
            if solver is not None:  # its inertia is trusted; otherwise QDLDL factorises this matrix
                self._U, self._solver, self.d, self.backend = U, solver, solver.d, "pardiso"
                return
        elif isinstance(getattr(previous, "_solver", None), pardiso.PardisoSolver):
            previous = None  # QDLDL cannot take over PARDISO's analysis
        pooled = None
        if previous is None or previous._solver is None:
            pooled = _POOL.take(U)
        if pooled is not None:
            solver = _refactorise(pooled, U)
        elif (
            previous is not None
            and previous._solver is not None
            and previous._U.shape == U.shape
            and np.array_equal(previous._U.indptr, U.indptr)
            and np.array_equal(previous._U.indices, U.indices)
        ):
            solver = previous._solver
            previous._solver = None  # the qdldl object now holds this matrix
            solver = _refactorise(solver, U)
        else:
            try:
                solver = qdldl.Solver(U, upper=True)
            except (RuntimeError, ValueError) as exc:  # zero pivot: not quasi-definite in this ordering
                raise SingularMatrixError(f"LDL^T factorisation failed: {exc}") from None
        self._U = U
        self._solver = solver
        self._d = None

    @property
    def d(self) -> np.ndarray:
        """The pivots (the diagonal of ``D``), read from the factor when first asked for.

        qdldl hands them out only with the whole ``L`` (see :func:`_refactorise`).

        Raises
        ------
        SingularMatrixError
            When a pivot is zero or not finite, or the factor gave its storage
            to a later one before they were read.
        """
        if self._d is None:
            if self._solver is None:
                raise SingularMatrixError("this LDL^T factor gave its storage to a later factorisation before "
                                          "its pivots were read")
            d = np.asarray(self._solver.factors()[1], dtype=float)
            if not np.all(np.isfinite(d)) or np.any(d == 0.0):
                raise SingularMatrixError("LDL^T factorisation met a zero pivot (matrix singular in this ordering)")
            self._d = d
        return self._d

    @d.setter
    def d(self, value) -> None:
        self._d = value

    def __del__(self):
        # the solver's ordering and symbolic factorisation serve the next factor of this pattern
        solver = getattr(self, "_solver", None)
        if solver is not None and _POOL is not None:
            self._solver = None
            getattr(solver, "pool", _POOL).give(self._U, solver)

    # -- inertia --------------------------------------------------------------------
    @property
    def inertia(self) -> tuple[int, int, int]:
        """Counts of (negative, zero, positive) pivots = eigenvalues by Sylvester's law."""
        neg = self.n_negative_pivots
        return neg, 0, self.n - neg  # a zero pivot raises where the pivots are read

    @property
    def n_negative_pivots(self) -> int:
        return int(np.count_nonzero(self.d < 0.0))

    @property
    def min_pivot_ratio(self) -> float:
        """Smallest ``|d_i|`` relative to the largest diagonal entry of the matrix."""
        return float(np.min(np.abs(self.d)) / self.scale) if self.n else np.inf

    @property
    def norm_inf(self) -> float:
        """Infinity norm of the factorised matrix (largest absolute row sum)."""
        if self._norm_inf is None:
            self._norm_inf = row_sum_norm(self.A)
        return self._norm_inf

    # -- solves ---------------------------------------------------------------------
    def _raw_solve(self, b: np.ndarray) -> np.ndarray:
        if self._solver is None:
            raise RuntimeError("this LDL^T factor gave its storage to a later factorisation (previous=...)")
        return self._solver.solve(b)

    def solve(self, b: np.ndarray, refine: int | None = None) -> np.ndarray:
        """Solve ``A x = b`` with iterative refinement.

        Parameters
        ----------
        b : ndarray
        refine : int, optional
            Most refinement steps (default: the factor's ``refine``); each
            stops as soon as the backward error is at the rounding level.

        Raises
        ------
        SingularMatrixError
            When the result is not finite or its backward error stays above
            ``check`` (a tiny pivot spoiled the factor, or ``A`` is singular).
        """
        b = np.asarray(b, dtype=float)
        steps = self.refine if refine is None else int(refine)
        x, eta = refined_solve(self.A, self._raw_solve, self.norm_inf, b, steps)
        failed = not np.all(np.isfinite(x)) or (self.check is not None and eta > self.check)
        if failed and self._to_qdldl():
            return self.solve(b, refine)
        if not np.all(np.isfinite(x)):
            raise SingularMatrixError("LDL^T solve produced non-finite values (matrix numerically singular)")
        if self.check is not None and eta > self.check:
            raise SingularMatrixError(
                f"LDL^T solve failed its backward-error check ({eta:.1e} > {self.check:.1e}): "
                "tiny pivot or singular matrix"
            )
        return x

    def backward_error(self) -> float:
        """Normwise backward error of an unrefined test solve with a random right-hand side."""
        rng = np.random.default_rng(12345)
        x_true = rng.standard_normal(self.n)
        b = self.A @ x_true
        x = self._raw_solve(b)
        if not np.all(np.isfinite(x)):
            return np.inf
        return normwise_backward_error(self.norm_inf, x, b, b - self.A @ x)

    def trustworthy(self, pivot_tol: float = 1e-10, backward_tol: float = 1e-11) -> bool:
        """Whether the pivot signs give the inertia: no tiny pivot, small backward error."""
        try:
            ratio = self.min_pivot_ratio
        except SingularMatrixError:  # a zero pivot
            return False
        if ratio <= pivot_tol:
            return False  # an eigenvalue may be near zero: the caller's shifted factorisations decide
        if self.backward_error() < backward_tol:
            return True
        try:  # a PARDISO factor's solve was not accurate enough: QDLDL's may be
            return self._to_qdldl() and self.trustworthy(pivot_tol, backward_tol)
        except SingularMatrixError:
            return False

    def _to_qdldl(self) -> bool:
        """Refactorise a PARDISO factor's matrix with QDLDL (False: it is QDLDL's already).

        Raises SingularMatrixError where a QDLDL factorisation would.
        """
        if self.backend != "pardiso":
            return False
        q = LDLFactor(self.A, check=self.check, refine=self.refine, backend="qdldl")
        # q is freed with the PARDISO solver, which goes back to its pool for the next matrix of the pattern
        d = q.d  # read while q still holds its own factor
        self._solver, q._solver = q._solver, self._solver
        self.d, self.backend = d, "qdldl"
        return True
