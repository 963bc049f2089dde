"""The linear-solver interface: answers, inertia, fallbacks and clear failures."""

import numpy as np
import pytest
import scipy.sparse as sp

from shellform.solvers.linear import CholeskyFactor, LDLFactor, SingularMatrixError, factorize


def laplacian_3d(n):
    """SPD test matrix: 1D Laplacian in each of x, y, z, interleaved by node."""
    T = sp.diags([-np.ones(n - 1), 2 * np.ones(n), -np.ones(n - 1)], [-1, 0, 1])
    return sp.kron(T, sp.eye(3)).tocsr()


@pytest.mark.parametrize("method", ["direct", "ldl", "lu", "cholesky", "amg", "auto"])
def test_solvers_agree_on_an_spd_system(method):
    A = laplacian_3d(50)
    x_true = np.random.default_rng(0).normal(size=A.shape[0])
    x = factorize(A, method).solve(A @ x_true)
    assert np.allclose(x, x_true, rtol=1e-7, atol=1e-7)


def test_ldl_inertia_matches_eigenvalues_of_an_indefinite_matrix():
    rng = np.random.default_rng(1)
    Q, _ = np.linalg.qr(rng.normal(size=(30, 30)))
    eig = np.concatenate([-rng.uniform(1, 2, 4), rng.uniform(1, 2, 26)])
    A = sp.csr_matrix(Q @ np.diag(eig) @ Q.T)
    F = factorize(A, "ldl")
    assert F.inertia == (4, 0, 26)
    b = rng.normal(size=30)
    assert np.allclose(A @ F.solve(b), b)


def test_direct_falls_back_to_lu_on_a_zero_pivot():
    # symmetric and non-singular, but a zero leading pivot in any ordering of this 2x2
    A = sp.csr_matrix(np.array([[0.0, 1.0], [1.0, 0.0]]))
    with pytest.raises(SingularMatrixError):  # at once, or where the pattern's kept analysis is refactorised, in the solve
        factorize(A, "ldl").solve([2.0, 3.0])
    assert np.allclose(factorize(A, "direct").solve([2.0, 3.0]), [3.0, 2.0])


@pytest.mark.parametrize("method", ["direct", "lu", "ldl", "cholesky"])
def test_singular_matrix_raises(method):
    A = sp.csr_matrix(np.array([[1.0, 1.0], [1.0, 1.0]]))
    with pytest.raises(SingularMatrixError):
        factorize(A, method).solve([1.0, 0.0])


def test_amg_refuses_an_indefinite_matrix():
    A = laplacian_3d(40) - 1.5 * sp.eye(120)
    with pytest.raises(SingularMatrixError, match="positive definite"):
        factorize(A, "amg").solve(np.ones(120))


def test_unknown_method():
    with pytest.raises(ValueError, match="unknown linear solver"):
        factorize(sp.eye(3), "magic")


def test_ldl_accepts_the_large_accurate_solution_of_a_nearly_singular_matrix():
    """Next to a critical point |x| >> |b|: the backward error, not |r| / |b|, judges the solve."""
    from scipy.sparse.linalg import eigsh

    A = laplacian_3d(40)
    lam_min = eigsh(A, k=1, sigma=0, which="LM", return_eigenvectors=False)[0]
    A = sp.csr_matrix(A - (lam_min - 1e-10) * sp.eye(A.shape[0]))  # smallest eigenvalue 1e-10
    b = np.random.default_rng(4).normal(size=A.shape[0])
    x = factorize(A, "ldl").solve(b)
    x_ref = np.linalg.solve(A.toarray(), b)
    assert np.max(np.abs(x)) > 1e8 * np.max(np.abs(b))
    assert np.allclose(x, x_ref, rtol=1e-4, atol=1e-4 * np.max(np.abs(x_ref)))


def test_ldl_factor_reused_on_the_same_pattern_gives_up_its_storage():
    A = laplacian_3d(10)
    F1 = LDLFactor(A)
    F2 = LDLFactor(2.0 * A, previous=F1)
    b = np.ones(A.shape[0])
    assert np.allclose(2.0 * (A @ F2.solve(b)), b)
    with pytest.raises(RuntimeError, match="later factorisation"):
        F1.solve(b)


def test_cholesky_refuses_an_indefinite_matrix():
    A = laplacian_3d(40) - 1.5 * sp.eye(120)
    with pytest.raises(SingularMatrixError, match="not positive definite"):
        CholeskyFactor(A)


def test_cholesky_reuses_its_analysis_on_the_same_pattern_and_redoes_it_on_another():
    A = laplacian_3d(10)
    rng = np.random.default_rng(5)
    b = rng.normal(size=(A.shape[0], 2))  # two right-hand sides at once
    F1 = CholeskyFactor(A)
    assert np.allclose(A @ F1.solve(b), b)
    # same pattern, other values: the analysis is taken over and F1 gives up its storage
    F2 = CholeskyFactor(3.0 * A + sp.eye(A.shape[0]), previous=F1)
    assert F2._symbolic is not None and F1._symbolic is None
    assert np.allclose((3.0 * A + sp.eye(A.shape[0])) @ F2.solve(b), b)
    with pytest.raises(SingularMatrixError, match="later factorisation"):
        F1.solve(b)
    # another pattern: a fresh analysis, the answer still right
    B = sp.csr_matrix(A + sp.diags(0.1 * np.ones(A.shape[0] - 6), 6) + sp.diags(0.1 * np.ones(A.shape[0] - 6), -6))
    F3 = CholeskyFactor(B, previous=F2)
    assert F2._symbolic is not None
    assert np.allclose(B @ F3.solve(b[:, 0]), b[:, 0])


def _with_explicit_zeros(A, rows):
    """``A`` with the off-diagonal entries of ``rows`` (and their mirrors) set to stored zeros."""
    A = sp.csr_matrix(A, copy=True)
    coo = A.tocoo()
    hit = (np.isin(coo.row, rows) | np.isin(coo.col, rows)) & (coo.row != coo.col)
    data = np.where(hit, 0.0, coo.data)
    out = sp.csr_matrix((data, (coo.row, coo.col)), shape=A.shape)
    assert out.nnz == A.nnz  # the zeros stay stored
    return out


def test_cholesky_leaves_exact_zeros_out_of_its_analysis():
    A = laplacian_3d(40) + sp.eye(120)
    b = np.random.default_rng(2).normal(size=A.shape[0])
    lower_nonzeros = lambda M: sp.tril(M).count_nonzero()  # noqa: E731
    A1 = _with_explicit_zeros(A, [4, 11])  # e.g. two slack members: the same stored pattern, other zeros
    F1 = CholeskyFactor(A1)
    assert len(F1._M.V) == lower_nonzeros(A1) < sp.tril(A1).nnz
    assert np.allclose(A1 @ F1.solve(b), b)
    # entries that became nonzero need a new analysis; F1 keeps its own
    A2 = _with_explicit_zeros(A, [7])
    F2 = CholeskyFactor(A2, previous=F1)
    assert F1._symbolic is not None
    assert np.allclose(A2 @ F2.solve(b), b)
    # fewer nonzeros, other values: the analysis is taken over while the zeros in it are few
    A3 = 2.0 * _with_explicit_zeros(A, [7, 20])
    F3 = CholeskyFactor(A3, previous=F2)
    assert F2._symbolic is None
    assert np.allclose(A3 @ F3.solve(b), b)
    # many more zeros: analysed afresh without them
    A4 = _with_explicit_zeros(A, np.arange(0, 120, 3))
    F4 = CholeskyFactor(A4, previous=F3)
    assert F3._symbolic is not None and len(F4._M.V) == lower_nonzeros(A4)
    assert np.allclose(A4 @ F4.solve(b), b)


def test_cholesky_names_a_row_without_a_diagonal_entry():
    A = sp.lil_matrix(laplacian_3d(10) + sp.eye(30))
    A[5, 5] = 0.0
    A = sp.csr_matrix(A)
    A.eliminate_zeros()
    with pytest.raises(SingularMatrixError, match="row 5 has no diagonal entry"):
        CholeskyFactor(A)


def test_a_freed_ldl_factor_lends_its_analysis_to_the_next_of_the_same_pattern():
    """The second factorisation of a pattern takes the first's ordering and symbolic analysis once
    the first is freed, and gives the same factor as a fresh analysis."""
    from shellform.solvers import ldl

    rng = np.random.default_rng(3)
    A = laplacian_3d(40)
    B = sp.csr_matrix((A.data * rng.uniform(0.5, 1.5, A.nnz), A.indices, A.indptr), shape=A.shape)
    B = sp.csr_matrix(0.5 * (B + B.T))
    ldl._POOL.clear()
    fresh = LDLFactor(B)
    d_fresh, x_fresh = fresh.d.copy(), fresh.solve(np.ones(B.shape[0]))
    del fresh
    assert len(ldl._POOL._items) == 1
    F = LDLFactor(A)  # same pattern: takes the pooled analysis
    assert len(ldl._POOL._items) == 0
    del F
    G = LDLFactor(B)
    assert np.array_equal(G.d, d_fresh)
    assert np.array_equal(G.solve(np.ones(B.shape[0])), x_fresh)
    # another pattern does not take it
    del G
    C = laplacian_3d(41)
    H = LDLFactor(C)
    assert len(ldl._POOL._items) == 1 and H.inertia == (0, 0, C.shape[0])


def test_diagonal_shift_keeps_the_pattern_with_its_explicit_zeros():
    from shellform.solvers.linear import shift_diagonal

    A = laplacian_3d(10)
    A.data[A.data == -1.0] = 0.0  # off-diagonal entries stored as explicit zeros (slack ropes)
    zeros = np.count_nonzero(A.data == 0.0)
    assert zeros > 0
    for sigma in (0.3, np.linspace(1.0, 2.0, A.shape[0])):
        B = shift_diagonal(A, sigma)
        assert np.array_equal(B.indptr, A.indptr) and np.array_equal(B.indices, A.indices)
        assert abs(B - (A + sp.diags(np.broadcast_to(sigma, (A.shape[0],))))).max() == 0.0
        assert np.count_nonzero(B.data == 0.0) == zeros


def test_dense_eigenvalues_run_on_one_blas_thread_inside_the_block_only():
    from threadpoolctl import threadpool_info

    from shellform.solvers.linear import single_threaded

    def blas_threads():
        return [i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"]

    before = blas_threads()
    with single_threaded():
        assert all(n == 1 for n in blas_threads())
    assert blas_threads() == before


def test_system_pattern_is_the_sorted_set_of_its_triplets():
    """The CSR pattern (and each triplet's slot in it) that every factorisation of a System works on,
    against a comparison sort of the triplets' keys; duplicates, empty rows and an unsorted input."""
    from shellform.sparse_pattern import Pattern

    rng = np.random.default_rng(7)
    n_rows, n_cols = 57, 41
    rows = rng.integers(0, n_rows - 3, 2000)  # the last rows stay empty
    cols = rng.integers(0, n_cols, 2000)
    P = Pattern(rows, cols, (n_rows, n_cols))
    key = rows * n_cols + cols
    unique, slot = np.unique(key, return_inverse=True)
    assert P.nnz == unique.size
    assert np.array_equal(P.slot, slot)
    assert np.array_equal(P.indices, unique % n_cols)
    assert np.array_equal(P.indptr, np.concatenate([[0], np.cumsum(np.bincount(unique // n_cols, minlength=n_rows))]))
    vals = rng.standard_normal(rows.size)
    dense = np.zeros((n_rows, n_cols))
    np.add.at(dense, (rows, cols), vals)
    assert np.allclose(P.matrix(vals).toarray(), dense, rtol=0, atol=1e-13)


def test_a_failed_cholesky_leaves_its_analysis_for_the_next():
    """Past a critical point Cholesky fails at every other trial: the analysis it reused goes back
    to the factor it came from (which can no longer solve) and serves the next factorisation."""
    from unittest import mock

    A = laplacian_3d(30)
    F = CholeskyFactor(A)
    indefinite = sp.csr_matrix(A - 3.0 * sp.identity(A.shape[0]), copy=True)
    indefinite = sp.csr_matrix((indefinite.data, indefinite.indices, indefinite.indptr), shape=A.shape)
    assert np.array_equal(indefinite.indices, A.indices)
    with pytest.raises(SingularMatrixError):
        CholeskyFactor(indefinite, previous=F)
    with pytest.raises(SingularMatrixError):
        F.solve(np.ones(A.shape[0]))  # its values were overwritten
    from cvxopt import cholmod

    with mock.patch.object(cholmod, "symbolic", side_effect=AssertionError("analysed again")):
        G = CholeskyFactor(2.0 * A, previous=F)
    x = G.solve(np.ones(A.shape[0]))
    assert np.allclose(2.0 * A @ x, 1.0)


def test_cholesky_of_every_stored_entry_needs_no_new_analysis_when_a_zero_turns_nonzero():
    from unittest import mock

    from cvxopt import cholmod

    A = laplacian_3d(30)
    D = A.toarray()
    for i, j in [(0, 3), (30, 33), (60, 63)]:  # a few incidental zeros (under ZERO_SHARE of the entries)
        D[i, j] = D[j, i] = 0.0
    B = sp.csr_matrix((D[A.nonzero()], A.indices, A.indptr), shape=A.shape)  # A's pattern, the zeros stored
    assert np.count_nonzero(B.data == 0.0) == 6
    F = CholeskyFactor(B, stored=True)
    with mock.patch.object(cholmod, "symbolic", side_effect=AssertionError("analysed again")):
        G = CholeskyFactor(A, previous=F, stored=True)
    assert np.allclose(A @ G.solve(np.ones(A.shape[0])), 1.0)
    # without it, the entries that became nonzero need a new analysis
    F = CholeskyFactor(B)
    with mock.patch.object(cholmod, "symbolic", side_effect=AssertionError("analysed again")):
        with pytest.raises(AssertionError):
            CholeskyFactor(A, previous=F)


def test_a_zero_pivot_never_gives_an_answer_whichever_analysis_the_factor_takes():
    """A fresh analysis raises at once; a kept one (pooled or from ``previous``, where qdldl's
    update stops at the zero pivot without a word) raises when the pivots are read or a solve is
    asked for; the analysis survives for the next matrix of the pattern."""
    from shellform.solvers import ldl

    A = laplacian_3d(20)
    S = A.copy()
    rows = np.repeat(np.arange(A.shape[0]), np.diff(A.indptr))
    S.data[(rows == 7) | (A.indices == 7)] = 0.0  # row and column 7 zero, kept in the pattern
    b = np.ones(A.shape[0])
    ldl._POOL.clear()
    with pytest.raises(SingularMatrixError):
        LDLFactor(S)  # fresh
    first = LDLFactor(A)
    del first  # its analysis goes to the pool
    pooled = LDLFactor(S)
    with pytest.raises(SingularMatrixError):
        pooled.solve(b)
    with pytest.raises(SingularMatrixError, match="zero pivot"):
        pooled.n_negative_pivots
    F = LDLFactor(A)
    taken = LDLFactor(S, previous=F)
    with pytest.raises(SingularMatrixError, match="zero pivot"):
        taken.inertia
    with pytest.raises(SingularMatrixError):
        taken.solve(b)
    G = LDLFactor(2.0 * A, previous=taken)
    assert G.inertia == (0, 0, A.shape[0])
    np.testing.assert_allclose(2.0 * A @ G.solve(b), b, atol=1e-12)


def test_pivots_are_read_from_qdldl_only_for_the_inertia():
    A = laplacian_3d(30)
    B = sp.csr_matrix(A - 1.3 * sp.identity(A.shape[0]))
    F = LDLFactor(B)
    x = F.solve(np.ones(B.shape[0]))
    assert F._d is None  # solving needs no pivots
    np.testing.assert_allclose(B @ x, np.ones(B.shape[0]), atol=1e-9)
    n_neg = int(np.sum(np.linalg.eigvalsh(B.toarray()) < 0.0))
    assert n_neg > 0 and F.n_negative_pivots == n_neg and F._d is not None
    G = LDLFactor(B)
    H = LDLFactor(B, previous=G)  # G gives its storage to H before its pivots were read
    with pytest.raises(SingularMatrixError, match="gave its storage"):
        G.d
    assert H.n_negative_pivots == n_neg


def test_a_non_finite_entry_is_named():
    A = laplacian_3d(10).tolil()
    A[4, 4] = np.nan
    with pytest.raises(SingularMatrixError, match="non-finite entry \\(row 4, column 4\\)"):
        LDLFactor(sp.csr_matrix(A))
