"""What every factorisation shares: its error, the upper triangle it reads, diagonal shifts, one BLAS thread."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp


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


def upper_csc(A) -> sp.csc_matrix:
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
