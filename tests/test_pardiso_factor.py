"""The PARDISO backend of LDLFactor: inertia and solves against QDLDL and dense, trust, the switch, pattern reuse."""

import gc
import weakref

import numpy as np
import pytest
import scipy.sparse as sp

from shellform.solvers import pardiso
from shellform.solvers.factor_base import shift_diagonal, upper_csc
from shellform.solvers.ldl import LDLFactor
from shellform.solvers.linear import SingularMatrixError
from shellform.solvers.stability import count_negative, inertia

needs_pardiso = pytest.mark.skipif(not pardiso.available(), reason="pypardiso is not installed")


def random_indefinite(n, negative, seed, density=0.02):
    """A sparse symmetric matrix with ``negative`` negative eigenvalues: a diagonal with entries of
    magnitude 0.5 to 2 plus symmetric coupling too weak to move one across zero."""
    rng = np.random.default_rng(seed)
    w = np.concatenate([-rng.uniform(0.5, 2.0, negative), rng.uniform(0.5, 2.0, n - negative)])
    A = sp.diags(rng.permutation(w)).tocsr()
    S = sp.random(n, n, density=density, random_state=seed)
    A = A + 1e-3 * (S + S.T)  # small enough not to move an eigenvalue across zero
    return sp.csr_matrix(A)


@pytest.fixture(autouse=True)
def default_backend(monkeypatch):
    monkeypatch.delenv(pardiso.BACKEND_VARIABLE, raising=False)


@needs_pardiso
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_inertia_and_solves_agree_with_qdldl_and_dense(seed):
    rng = np.random.default_rng(seed)
    n = 300
    B = sp.random(n, n, density=0.03, random_state=seed)
    A = sp.csr_matrix(B + B.T + sp.diags(rng.standard_normal(n)))
    w = np.linalg.eigvalsh(A.toarray())
    P = LDLFactor(A, backend="pardiso")
    Q = LDLFactor(A, backend="qdldl")
    assert P.backend == "pardiso" and Q.backend == "qdldl"
    assert P.n_negative_pivots == Q.n_negative_pivots == int(np.sum(w < 0))
    assert P.inertia == Q.inertia
    assert P.trustworthy()
    b = rng.standard_normal(n)
    assert np.allclose(P.solve(b), np.linalg.solve(A.toarray(), b), rtol=1e-8, atol=1e-10)
    # one solve per column as well
    Bm = rng.standard_normal((n, 3))
    assert np.allclose(P._raw_solve(Bm), np.linalg.solve(A.toarray(), Bm), rtol=1e-7, atol=1e-9)
    # the pivots are D's diagonal: their product is the determinant
    sign, logdet = np.linalg.slogdet(A.toarray())
    assert np.sum(np.log(np.abs(P.d))) == pytest.approx(logdet, rel=1e-9)
    assert np.prod(np.sign(P.d)) == sign
    # min_pivot_ratio keeps its meaning: the smallest |pivot| over A's largest diagonal entry
    assert P.min_pivot_ratio == pytest.approx(np.min(np.abs(P.d)) / np.max(np.abs(A.diagonal())))
    assert P.norm_inf == pytest.approx(Q.norm_inf)


@needs_pardiso
def test_a_many_negative_sparse_matrix():
    A = random_indefinite(2000, 700, seed=5)
    P = LDLFactor(A, backend="pardiso")
    assert P.backend == "pardiso"
    assert P.n_negative_pivots == 700 == LDLFactor(A, backend="qdldl").n_negative_pivots


@pytest.fixture(scope="module")
def hemisphere_tangent():
    from shellform.gridshell.hemisphere import HemisphereSpec, build_hemisphere, prestress_on_net
    from shellform.gridshell.indentation import indentation_system

    m = build_hemisphere(HemisphereSpec(5, voronoi_length=4.0e-3))
    pre = prestress_on_net(m)
    K = indentation_system(m, pre, mode="I").system.tangent_free(pre.q).tocsr()
    return K, np.linalg.eigvalsh(K.toarray())


@needs_pardiso
@pytest.mark.parametrize("below", [0, 2, 4, 5, 6, 10])  # between distinct eigenvalues (pairs are double)
def test_hemisphere_tangent_shifted_between_eigenvalues(hemisphere_tangent, below):
    K, w = hemisphere_tangent
    sigma = 0.5 * (w[below - 1] + w[below]) if below else 0.0
    A = shift_diagonal(K, -sigma)
    P = LDLFactor(A, backend="pardiso")
    Q = LDLFactor(A, backend="qdldl")
    assert P.backend == "pardiso"
    assert P.n_negative_pivots == Q.n_negative_pivots == below
    b = np.random.default_rng(below).standard_normal(K.shape[0])
    x = P.solve(b)
    assert np.allclose(x, Q.solve(b), rtol=1e-7, atol=1e-9 * np.max(np.abs(x)))
    assert count_negative(A) == below  # through the default backend (either)


@needs_pardiso
def test_stability_counts_through_pardiso(hemisphere_tangent, monkeypatch):
    monkeypatch.setenv(pardiso.BACKEND_VARIABLE, "pardiso")
    K, w = hemisphere_tangent
    A = shift_diagonal(K, -0.5 * (w[4] + w[5]))
    assert LDLFactor(A).backend == "pardiso"
    assert count_negative(A) == 5
    found = inertia(A)
    # eigenvalues 1e-12 of the largest diagonal entry count as zero, as with QDLDL
    monkeypatch.setenv(pardiso.BACKEND_VARIABLE, "qdldl")
    ref = inertia(A)
    assert (found.n_negative, found.n_zero, found.n_positive, found.n_below_zero, found.method) == (
        ref.n_negative, ref.n_zero, ref.n_positive, ref.n_below_zero, ref.method)
    assert found.n_below_zero == 5
    # the smallest pivot depends on the ordering, not its order of magnitude (an eigenvalue 1e-12 of the scale)
    assert 1e-15 < found.min_pivot_ratio < 1e-13 and 1e-15 < ref.min_pivot_ratio < 1e-13


@needs_pardiso
def test_perturbed_pivots_hand_over_to_qdldl():
    # a nearly singular indefinite 2x2 block: without 2x2 pivots PARDISO meets a pivot of 1e-14, below
    # its perturbation threshold of 1e-13 ||A||; QDLDL factorises it (pivots 1e-14 and -1e14)
    near = sp.csr_matrix([[1e-14, 1.0], [1.0, 1e-14]])
    A = sp.block_diag([random_indefinite(400, 40, seed=7), near]).tocsr()
    s = pardiso.PardisoSolver(upper_csc(A))
    assert s.n_perturbed == 1 and not s.trusted()
    del s
    F = LDLFactor(A, backend="pardiso")
    assert F.backend == "qdldl"  # the perturbed factor was not used
    assert F.n_negative_pivots == 41
    assert not F.trustworthy()  # the tiny pivot: stability's shifted factorisations decide
    assert inertia(A).n_negative == 41
    # above the threshold the pivot is PARDISO's own, and trusted
    B = sp.block_diag([random_indefinite(400, 40, seed=7), sp.csr_matrix([[1e-10, 1.0], [1.0, 1e-10]])]).tocsr()
    G = LDLFactor(B, backend="pardiso")
    assert G.backend == "pardiso" and G.n_negative_pivots == 41


@needs_pardiso
def test_singular_matrix_raises_where_qdldl_does():
    A = random_indefinite(300, 30, seed=3).tolil()
    A[7, :] = 0.0
    A[:, 7] = 0.0
    A[7, 7] = 0.0
    A = sp.csr_matrix(A)  # upper_csc stores the zero diagonal entry
    s = pardiso.PardisoSolver(upper_csc(A))
    assert s.n_perturbed > 0  # PARDISO replaced the zero pivot
    del s
    for backend in ("qdldl", "pardiso"):
        with pytest.raises(SingularMatrixError):
            LDLFactor(A, backend=backend)


@needs_pardiso
def test_a_solve_failing_its_check_hands_over_to_qdldl(monkeypatch):
    A = random_indefinite(400, 40, seed=8)
    F = LDLFactor(A, backend="pardiso")
    assert F.backend == "pardiso"
    good = pardiso.PardisoSolver.solve
    monkeypatch.setattr(pardiso.PardisoSolver, "solve", lambda self, b: 1.5 * good(self, b))
    b = np.ones(A.shape[0])
    x = F.solve(b)
    assert F.backend == "qdldl"
    assert np.allclose(A @ x, b)
    G = LDLFactor(A, backend="pardiso")
    assert G.trustworthy() and G.backend == "qdldl"


@needs_pardiso
def test_the_analysis_is_reused_by_pattern():
    pardiso._POOL.clear()
    A = random_indefinite(500, 50, seed=9)
    F = LDLFactor(A, backend="pardiso")
    solver = F._solver
    # previous=: the new factor takes the solver over, the old one cannot solve any more
    G = LDLFactor(2.0 * A, previous=F, backend="pardiso")
    assert G._solver is solver
    with pytest.raises(RuntimeError):
        F.solve(np.ones(500))
    # a freed factor's solver serves the next factor of its pattern
    del F, G
    gc.collect()
    H = LDLFactor(3.0 * A, backend="pardiso")
    assert H._solver is solver
    b = np.ones(500)
    assert np.allclose(3.0 * (A @ H.solve(b)), b)
    # another pattern gets its own analysis; a solver dropped from the pool is freed (phase -1)
    ref = weakref.ref(solver)
    released = []
    monkeypatch = pytest.MonkeyPatch()
    monkeypatch.setattr(pardiso.PardisoSolver, "release",
                        lambda self, _release=pardiso.PardisoSolver.release: (released.append(1), _release(self)))
    try:
        del H, solver
        for seed in (10, 11, 12):
            LDLFactor(random_indefinite(500, 50, seed=seed), backend="pardiso")
        gc.collect()
        assert ref() is None and released
    finally:
        monkeypatch.undo()
        pardiso._POOL.clear()


@needs_pardiso
def test_a_released_solver_is_never_reused():
    # a reference cycle: the collector may finalise the solver (phase -1) before the factor gives it back
    pardiso._POOL.clear()
    A = random_indefinite(300, 30, seed=13)
    for _ in range(3):
        F = LDLFactor(A, backend="pardiso")
        F.cycle = F
        del F
        gc.collect()
    G = LDLFactor(2.0 * A, backend="pardiso")
    assert G.backend == "pardiso" and G.n_negative_pivots == 30
    G._solver.release()
    with pytest.raises(pardiso.PardisoError):
        G._solver.solve(np.ones(300))
    pardiso._POOL.clear()


@needs_pardiso
def test_non_finite_values_raise_as_with_qdldl():
    A = random_indefinite(300, 30, seed=14).tolil()
    A[5, 5] = np.nan
    A = sp.csr_matrix(A)
    for backend in ("qdldl", "pardiso"):
        with pytest.raises(SingularMatrixError):
            LDLFactor(A, backend=backend)


def test_the_backend_switch(monkeypatch):
    A = random_indefinite(200, 20, seed=4)
    monkeypatch.setenv(pardiso.BACKEND_VARIABLE, "qdldl")
    assert LDLFactor(A).backend == "qdldl"
    monkeypatch.setenv(pardiso.BACKEND_VARIABLE, "auto")
    assert LDLFactor(A).backend == "qdldl"  # below MIN_SIZE
    monkeypatch.setenv(pardiso.BACKEND_VARIABLE, "mumps")
    with pytest.raises(ValueError, match="SHELLFORM_LDL"):
        LDLFactor(A)
    monkeypatch.delenv(pardiso.BACKEND_VARIABLE)
    with pytest.raises(ValueError, match="unknown LDL"):
        LDLFactor(A, backend="cholmod")
    monkeypatch.setattr(pardiso, "MIN_SIZE", 100)
    expected = "pardiso" if pardiso.available() else "qdldl"
    assert LDLFactor(A).backend == expected  # auto: PARDISO from MIN_SIZE up, where installed
    monkeypatch.setenv(pardiso.BACKEND_VARIABLE, "pardiso")
    if pardiso.available():
        assert LDLFactor(A).backend == "pardiso"
    else:
        with pytest.raises(ImportError, match="pypardiso"):
            LDLFactor(A)


def grid_laplacian_3d(n, diagonal=2.2):
    T = sp.diags([-np.ones(n - 1), diagonal * np.ones(n), -np.ones(n - 1)], [-1, 0, 1])
    I = sp.identity(n)
    return sp.csr_matrix(sp.kron(sp.kron(T, I), I) + sp.kron(sp.kron(I, T), I) + sp.kron(sp.kron(I, I), T))


@needs_pardiso
def test_auto_sends_a_small_pattern_with_much_fill_to_pardiso_after_its_first_factorisation():
    """Below MIN_SIZE the fill decides: an 18^3 grid (5,832 unknowns, 1.3e8 multiply-adds by QDLDL) goes to
    PARDISO from its first factorisation on, whatever ran before; a band matrix of the same size stays."""
    from shellform.solvers import ldl

    A = grid_laplacian_3d(18)
    assert A.shape[0] < pardiso.MIN_SIZE
    ldl._COSTS._items.clear()
    first = LDLFactor(A)
    assert first.backend == "pardiso" and ldl._COSTS.get(upper_csc(A)) >= pardiso.MIN_MULTIPLY_ADDS
    second = LDLFactor(1.5 * A)
    assert second.backend == "pardiso" and second.inertia == first.inertia == (0, 0, A.shape[0])
    ldl._COSTS._items.clear()
    assert np.array_equal(LDLFactor(A).solve(np.ones(A.shape[0])), first.solve(np.ones(A.shape[0])))
    b = np.ones(A.shape[0])
    np.testing.assert_allclose(1.5 * A @ second.solve(b), b, atol=1e-10)
    n = A.shape[0]
    R = sp.csr_matrix(sp.diags([-np.ones(n - 1), np.where(np.arange(n) % 7 == 0, -3.0, 3.0), -np.ones(n - 1)],
                               [-1, 0, 1]))
    assert LDLFactor(R).backend == "qdldl" and ldl._COSTS.get(upper_csc(R)) < pardiso.MIN_MULTIPLY_ADDS
    assert LDLFactor(R).backend == "qdldl"
