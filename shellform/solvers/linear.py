"""Linear solves behind one small interface.

``factorize(A, method)`` returns an object with ``solve(b)``. Methods:

* ``"direct"`` (default): sparse LDL^T (QDLDL with AMD ordering) for the
  symmetric tangents shellform assembles; when it meets a zero pivot or its
  solution fails a backward-error check, SuperLU LU with partial pivoting takes
  over. Measured on a 148k-DOF rope-net tangent: QDLDL 6.6 s, SuperLU 150 s
  (``benchmarks/bench_assembly.py``). The LDL^T factor (:class:`LDLFactor`,
  the same one :mod:`shellform.solvers.stability` and the continuation use)
  also gives the inertia (number of negative eigenvalues, Sylvester's law).
* ``"ldl"``, ``"lu"``: one of the two, without fallback.
* ``"cholesky"``: supernodal Cholesky (CHOLMOD) for symmetric positive
  definite matrices, several times faster than LDL^T on large ones
  (:class:`CholeskyFactor`); it fails instead of returning an inertia.
* ``"amg"``: conjugate gradients preconditioned by pyamg's smoothed-aggregation
  multigrid. For large symmetric positive definite tangents only (taut rope nets
  and stable states); it reports failure instead of returning a wrong answer.
* ``"auto"``: ``"amg"`` above ``amg_threshold`` unknowns, ``"direct"`` below.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla


class SingularMatrixError(RuntimeError):
    """The matrix could not be factorised or the solve did not converge."""


_CONTROLLER = None


def single_threaded():
    """A context in which BLAS and LAPACK run on one thread (threadpoolctl).

    The dense eigenvalue solves of small models are a few milliseconds of
    BLAS calls too small to share: on the 2-core reference machine under
    load, ``eigvalsh`` of a 400 x 400 matrix took 81 ms (median of 30; up to
    3.4 s) with two OpenBLAS threads and 12 ms limited to one; at 100 x 100,
    16 ms against 0.55 ms (``benchmarks/bench_dense_threads.py``). The limit
    holds inside the block only, so the caller's own settings are untouched;
    entering it costs 0.02 ms.
    """
    global _CONTROLLER
    if _CONTROLLER is None:
        import scipy.linalg  # noqa: F401  (loads the BLAS the controller must see)
        from threadpoolctl import ThreadpoolController

        _CONTROLLER = ThreadpoolController()
    return _CONTROLLER.limit(limits=1, user_api="blas")


def _upper_csc(A) -> sp.csc_matrix:
    """Upper triangle of a symmetric matrix in CSC form, diagonal always stored.

    For a symmetric matrix the lower triangle of its CSR arrays is the upper
    triangle in CSC form, so no transpose is needed. Explicit zeros are kept so
    that the pattern (and qdldl's symbolic factorisation) does not change
    when an entry happens to vanish.
    """
    A = sp.csr_matrix(A)
    if not A.has_canonical_format:
        A = A.copy()
        A.sum_duplicates()
    n = A.shape[0]
    row = np.repeat(np.arange(n), np.diff(A.indptr))
    has_diag = np.zeros(n, dtype=bool)
    has_diag[row[A.indices == row]] = True
    if not has_diag.all():
        missing = np.flatnonzero(~has_diag)
        coo = A.tocoo()
        r = np.concatenate([coo.row, missing])
        c = np.concatenate([coo.col, missing])
        v = np.concatenate([coo.data, np.zeros(missing.size)])
        A = sp.csr_matrix((v, (r, c)), shape=A.shape)
        A.sum_duplicates()
        row = np.repeat(np.arange(n), np.diff(A.indptr))
    keep = A.indices <= row
    counts = np.bincount(row[keep], minlength=n)
    indptr = np.concatenate([[0], np.cumsum(counts)])
    return sp.csc_matrix((A.data[keep], A.indices[keep], indptr), shape=A.shape)


def shift_diagonal(A, sigma) -> sp.csr_matrix:
    """``A + diag(sigma)`` (a number or one per row) on the pattern of ``A``.

    A sparse sum drops entries that happen to be zero, and with them the
    sparsity pattern a kept symbolic analysis was made for; this keeps it
    when ``A`` stores its whole diagonal (every tangent of a System does).
    """
    A = sp.csr_matrix(A)
    n = A.shape[0]
    row = np.repeat(np.arange(n), np.diff(A.indptr))
    on_diag = np.flatnonzero(A.indices == row)
    if on_diag.size != n or not A.has_canonical_format:
        return sp.csr_matrix(A + sp.diags(np.broadcast_to(np.asarray(sigma, dtype=float), (n,))))
    B = sp.csr_matrix((A.data.copy(), A.indices, A.indptr), shape=A.shape)
    B.data[on_diag] += sigma
    return B


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
            if indptr.shape == U.indptr.shape and indices.shape == U.indices.shape and np.array_equal(
                    indptr, U.indptr) and np.array_equal(indices, U.indices):
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


class LDLFactor:
    """Sparse ``L D L^T`` of a symmetric matrix (QDLDL, AMD ordering, no pivoting).

    One factor serves solves (Newton, continuation, shift-invert Lanczos) and
    stability: by Sylvester's law ``A`` has as many negative eigenvalues as
    ``D`` has negative entries. Without pivoting a factorisation of an
    indefinite matrix can meet a tiny pivot or grow large entries, so

    * a zero or non-finite pivot raises :class:`SingularMatrixError`;
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

    Raises
    ------
    SingularMatrixError
        When a pivot is zero or not finite.
    """

    method = "ldl"

    def __init__(self, A, previous: LDLFactor | None = None, check: float | None = 1e-9, refine: int = 3):
        import qdldl

        U = _upper_csc(A)
        self.A = sp.csr_matrix(A)
        self.n = U.shape[0]
        self.check = check
        self.refine = int(refine)
        self.scale = float(np.max(np.abs(U.diagonal()))) if self.n else 0.0
        if self.scale == 0.0:
            self.scale = float(np.max(np.abs(U.data))) if U.nnz else 1.0
        self._solver = None
        pooled = None
        if previous is None or previous._solver is None:
            pooled = _POOL.take(U)
        if pooled is not None:
            solver = pooled
            try:
                solver.update(U, upper=True)
            except (RuntimeError, ValueError) as exc:
                raise SingularMatrixError(f"LDL^T factorisation failed: {exc}") from None
        elif (
            previous is not None
            and previous._solver is not None
            and previous._U.shape == U.shape
            and np.array_equal(previous._U.indptr, U.indptr)
            and np.array_equal(previous._U.indices, U.indices)
        ):
            solver = previous._solver
            previous._solver = None  # the qdldl object now holds this matrix
            try:
                solver.update(U, upper=True)
            except (RuntimeError, ValueError) as exc:
                raise SingularMatrixError(f"LDL^T factorisation failed: {exc}") from None
        else:
            try:
                solver = qdldl.Solver(U, upper=True)
            except (RuntimeError, ValueError) as exc:  # zero pivot: not quasi-definite in this ordering
                raise SingularMatrixError(f"LDL^T factorisation failed: {exc}") from None
        self._U = U
        d = np.asarray(solver.factors()[1], dtype=float)
        # qdldl's update does not report a zero pivot itself
        if not np.all(np.isfinite(d)) or np.any(d == 0.0):
            raise SingularMatrixError("LDL^T factorisation met a zero pivot (matrix singular in this ordering)")
        self._solver = solver
        self.d = d
        self._norm_inf = None

    def __del__(self):
        # the solver's ordering and symbolic factorisation serve the next factor of this pattern
        solver = getattr(self, "_solver", None)
        if solver is not None and _POOL is not None:
            self._solver = None
            _POOL.give(self._U, solver)

    # -- inertia --------------------------------------------------------------------
    @property
    def inertia(self) -> tuple[int, int, int]:
        """Counts of (negative, zero, positive) pivots = eigenvalues by Sylvester's law."""
        neg = self.n_negative_pivots
        return neg, 0, self.n - neg  # a zero pivot raises in the constructor

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
            self._norm_inf = float(abs(self.A).sum(axis=1).max()) if self.n else 0.0
        return self._norm_inf

    # -- solves ---------------------------------------------------------------------
    def _raw_solve(self, b: np.ndarray) -> np.ndarray:
        if self._solver is None:
            raise RuntimeError("this LDL^T factor gave its storage to a later factorisation (previous=...)")
        return self._solver.solve(b)

    def _backward_error(self, x: np.ndarray, b: np.ndarray, r: np.ndarray) -> float:
        denom = self.norm_inf * float(np.max(np.abs(x), initial=0.0)) + float(np.max(np.abs(b), initial=0.0))
        res = float(np.max(np.abs(r), initial=0.0))
        return res / denom if denom > 0.0 else (0.0 if res == 0.0 else np.inf)

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
        x = self._raw_solve(b)
        eta = np.inf
        for k in range(steps + 1):
            if not np.all(np.isfinite(x)):
                break
            r = b - self.A @ x
            eta = self._backward_error(x, b, r)
            if eta <= 1e-12 or k == steps:
                break
            x = x + self._raw_solve(r)
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
        return self._backward_error(x, b, b - self.A @ x)

    def trustworthy(self, pivot_tol: float = 1e-10, backward_tol: float = 1e-11) -> bool:
        """Whether the pivot signs give the inertia: no tiny pivot, small backward error."""
        return self.min_pivot_ratio > pivot_tol and self.backward_error() < backward_tol


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
    SingularMatrixError
        When ``A`` is not (numerically) positive definite.
    """

    method = "cholesky"

    def __init__(self, A, previous: CholeskyFactor | None = None, stored: bool = False):
        from cvxopt import cholmod, matrix, spmatrix

        A = sp.csr_matrix(A)
        if not A.has_canonical_format:
            A = A.copy()
            A.sum_duplicates()
        self.shape = A.shape
        n = A.shape[0]
        same_pattern = (previous is not None and previous._symbolic is not None
                        and np.array_equal(previous._indptr, A.indptr) and np.array_equal(previous._indices, A.indices))
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
            raise SingularMatrixError(
                f"Cholesky factorisation failed (pivot {exc} of the reordered matrix is not positive): "
                "the matrix is not positive definite"
            ) from None

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


class LUFactor:
    """Sparse LU factorisation with partial pivoting (SuperLU)."""

    method = "lu"

    def __init__(self, A: sp.spmatrix):
        try:
            # MMD on A^T + A suits the structurally symmetric tangents we build
            self._lu = spla.splu(sp.csc_matrix(A), permc_spec="MMD_AT_PLUS_A")
        except RuntimeError as exc:  # "Factor is exactly singular"
            raise SingularMatrixError(f"sparse LU failed: {exc}") from None

    def solve(self, b: np.ndarray) -> np.ndarray:
        x = self._lu.solve(np.asarray(b, dtype=float))
        if not np.all(np.isfinite(x)):
            raise SingularMatrixError("sparse LU solve produced non-finite values (matrix numerically singular)")
        return x


class DirectFactor:
    """LDL^T where it works, LU where it does not (see the module docstring)."""

    method = "direct"

    def __init__(self, A: sp.spmatrix):
        self._ldl = None
        try:
            self._ldl = LDLFactor(A)
            self._impl = self._ldl
        except SingularMatrixError:
            self._impl = LUFactor(A)

    def solve(self, b: np.ndarray) -> np.ndarray:
        try:
            return self._impl.solve(b)
        except SingularMatrixError:
            if self._impl is not self._ldl:
                raise
            self._impl = LUFactor(self._ldl.A)
            return self._impl.solve(b)


class AMGFactor:
    """CG with a smoothed-aggregation AMG preconditioner (SPD matrices)."""

    method = "amg"

    def __init__(self, A: sp.spmatrix, rtol: float = 1e-10, maxiter: int = 500):
        import pyamg

        self.A = sp.csr_matrix(A)
        self.rtol = rtol
        self.maxiter = maxiter
        n = self.A.shape[0]
        if n % 3 == 0:
            # nodal unknowns come in xyz triples: aggregate by node and keep the
            # three translations in the coarse spaces (near-null space of a net)
            B = np.kron(np.ones((n // 3, 1)), np.eye(3))
            self._ml = pyamg.smoothed_aggregation_solver(self.A.tobsr(blocksize=(3, 3)), B=B, symmetry="symmetric")
        else:
            self._ml = pyamg.smoothed_aggregation_solver(self.A, symmetry="symmetric")
        #: one V-cycle as a linear operator, for callers running their own Krylov method
        self.preconditioner = self._ml.aspreconditioner(cycle="V")

    def solve(self, b: np.ndarray) -> np.ndarray:
        x, info = spla.cg(self.A, b, rtol=self.rtol, maxiter=self.maxiter, M=self.preconditioner)
        if info != 0 or not np.all(np.isfinite(x)):
            raise SingularMatrixError(
                f"AMG-preconditioned CG did not converge (info={info}); the matrix may not be positive definite"
            )
        return x


def factorize(A: sp.spmatrix, method: str = "direct", amg_threshold: int = 200_000):
    """Factorise ``A`` for repeated solves.

    Parameters
    ----------
    A : sparse matrix
        Square system matrix.
    method : {"direct", "ldl", "lu", "cholesky", "amg", "auto"}
        See the module docstring.
    amg_threshold : int
        Size above which ``"auto"`` picks AMG.
    """
    if method == "auto":
        method = "amg" if A.shape[0] > amg_threshold else "direct"
    if method == "direct":
        return DirectFactor(A)
    if method == "ldl":
        return LDLFactor(A)
    if method == "lu":
        return LUFactor(A)
    if method == "cholesky":
        return CholeskyFactor(A)
    if method == "amg":
        return AMGFactor(A)
    raise ValueError(f"unknown linear solver {method!r}; expected 'direct', 'ldl', 'lu', 'cholesky', 'amg' or 'auto'")
