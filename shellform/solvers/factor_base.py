"""What every factorisation shares: its error, the upper triangle it reads, diagonal shifts, one BLAS thread."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp


class SingularMatrixError(RuntimeError):
    """The matrix could not be factorised or the solve did not converge."""


class NotPositiveDefiniteError(SingularMatrixError):
    """A Cholesky factorisation met a pivot that is not positive: the matrix is not positive definite."""


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


class _Pattern:
    """What :func:`upper_csc` and :func:`shift_diagonal` work out from a CSR sparsity pattern alone.

    A run factorises the tangents of one System, and their shifts, hundreds of
    times on one pattern: on the n = 5 hemisphere's free tangent (3,688 rows,
    65,872 entries) working the upper triangle out afresh took 0.52 ms of
    every LDL^T factorisation, taken from here 0.06 ms, and a shift of the
    diagonal 0.19 ms against 0.04 ms. The pattern's own arrays are kept as
    copies (the matrices' may be changed in place later) and compared entry by
    entry (0.02 ms); the upper triangle's index arrays are shared by the
    matrices made from them, read-only.
    """

    def __init__(self, indptr: np.ndarray, indices: np.ndarray, n: int):
        self.indptr, self.indices = indptr.copy(), indices.copy()
        A = sp.csr_matrix((np.zeros(indices.size), self.indices, self.indptr), shape=(n, n))
        self.canonical = bool(A.has_canonical_format)
        row = np.repeat(np.arange(n), np.diff(indptr))
        self.diagonal = np.flatnonzero(indices == row)  # the slots of the diagonal, when each row has one
        self.complete = self.canonical and self.diagonal.size == n
        self.upper = None
        if self.complete:
            keep = indices <= row
            counts = np.bincount(row[keep], minlength=n)
            self.upper = (np.flatnonzero(keep), _read_only(indices[keep]),
                          _read_only(np.concatenate([[0], np.cumsum(counts)]).astype(indptr.dtype)))

    def matches(self, A) -> bool:
        return (A.indptr.shape == self.indptr.shape and A.indices.shape == self.indices.shape
                and np.array_equal(A.indptr, self.indptr) and np.array_equal(A.indices, self.indices))


def _read_only(a: np.ndarray) -> np.ndarray:
    a.flags.writeable = False
    return a


#: the patterns met last, most recent first (a run meets one or two: the free tangent, a full one)
_PATTERNS: list[_Pattern] = []
_PATTERNS_KEPT = 4


def _pattern(A: sp.csr_matrix) -> _Pattern:
    for k, p in enumerate(_PATTERNS):
        if p.matches(A):
            if k:
                _PATTERNS.insert(0, _PATTERNS.pop(k))
            return p
    p = _Pattern(A.indptr, A.indices, A.shape[0])
    _PATTERNS.insert(0, p)
    del _PATTERNS[_PATTERNS_KEPT:]
    return p


def upper_csc(A) -> sp.csc_matrix:
    """Upper triangle of a symmetric matrix in CSC form, diagonal always stored.

    For a symmetric matrix the lower triangle of its CSR arrays is the upper
    triangle in CSC form, so no transpose is needed. Explicit zeros are kept so
    that the pattern (and qdldl's symbolic factorisation) does not change
    when an entry happens to vanish. The index arrays of a canonical pattern
    with its whole diagonal are worked out once (:class:`_Pattern`).
    """
    A = sp.csr_matrix(A)
    if A.shape[0] == A.shape[1]:
        p = _pattern(A)
        if p.upper is not None:
            keep, indices, indptr = p.upper
            return sp.csc_matrix((A.data[keep], indices, indptr), shape=A.shape)
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
    p = _pattern(A) if A.shape[0] == A.shape[1] else None
    if p is None or not p.complete:
        return sp.csr_matrix(A + sp.diags(np.broadcast_to(np.asarray(sigma, dtype=float), (n,))))
    data = A.data.copy()
    data[p.diagonal] += sigma
    return sp.csr_matrix((data, A.indices, A.indptr), shape=A.shape)


def row_sum_norm(A: sp.csr_matrix) -> float:
    """Infinity norm of a CSR matrix (largest absolute row sum)."""
    if A.shape[0] == 0:
        return 0.0
    if np.all(np.diff(A.indptr) > 0):  # row sums by segments: half the time of a sparse |A| times ones
        return float(np.max(np.add.reduceat(np.abs(A.data), A.indptr[:-1])))
    return float(abs(A).sum(axis=1).max())


def normwise_backward_error(norm_a: float, x: np.ndarray, b: np.ndarray, r: np.ndarray) -> float:
    """Normwise backward error ``|r| / (|A| |x| + |b|)`` of ``x`` with residual ``r = b - A x`` (infinity norms).

    Unlike a residual relative to ``|b|`` alone, it accepts the large but
    accurate solutions next to a critical point, where ``A`` is nearly singular.
    """
    denom = norm_a * float(np.max(np.abs(x), initial=0.0)) + float(np.max(np.abs(b), initial=0.0))
    res = float(np.max(np.abs(r), initial=0.0))
    return res / denom if denom > 0.0 else (0.0 if res == 0.0 else np.inf)


def refined_solve(A, raw_solve, norm_a: float, b: np.ndarray, steps: int) -> tuple[np.ndarray, float]:
    """``raw_solve(b)`` with up to ``steps`` steps of iterative refinement; the solution and its backward error.

    Each step stops as soon as the backward error is at the rounding level.
    """
    x = raw_solve(b)
    eta = np.inf
    for k in range(steps + 1):
        if not np.all(np.isfinite(x)):
            break
        r = b - A @ x
        eta = normwise_backward_error(norm_a, x, b, r)
        if eta <= 1e-12 or k == steps:
            break
        x = x + raw_solve(r)
    return x, eta
