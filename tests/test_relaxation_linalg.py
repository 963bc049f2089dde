"""The relaxation's linear solves: the kept factor, its iteration budget, nested dissection, other solvers."""

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from test_relaxation import small_net

from shellform.solvers.relaxation import nested_dissection, relax


def test_kept_factor_budget_follows_the_measured_cost_ratios_not_the_clock():
    from shellform.solvers.relaxation import REFACTOR_COST, iteration_budget

    # half the measured refactorisation/iteration ratio at the measured sizes
    for method, points in REFACTOR_COST.items():
        for n, ratio in points:
            assert iteration_budget(method, n) == round(min(max(0.5 * ratio, 5), 60))
    # constant below the smallest measured size, growing as the last two sizes above the largest
    (n1, r1), (n2, r2), (n3, r3) = REFACTOR_COST["cholesky"]
    assert iteration_budget("cholesky", n1 / 30) == iteration_budget("cholesky", n1) == 5
    growth = np.log(r3 / r2) / np.log(n3 / n2)
    assert iteration_budget("cholesky", 10 * n3) == round(0.5 * r3 * 10**growth)
    assert iteration_budget("ldl", 1e8) == 60 and iteration_budget("amg", 10) == 10


def test_old_factor_is_tried_only_while_it_tends_to_work():
    from scipy.sparse import diags

    from shellform.solvers.relaxation.linalg import SPDSolve

    rng = np.random.default_rng(3)
    n = 200
    main = 4.0 + rng.random(n)
    A = diags([-np.ones(n - 1), main, -np.ones(n - 1)], [-1, 0, 1], format="csr")
    B = diags([-np.ones(n - 1), main * 10.0 ** rng.uniform(0, 4, n), -np.ones(n - 1)], [-1, 0, 1], format="csr")
    b = rng.standard_normal(n)
    # the rate alone, without the correction on the changed rows (here every row changes)
    solver = SPDSolve("cholesky", n, cg_max=2, correct=False)

    def attempted(M):
        before = solver.cg_iterations
        x = solver.solve(M, b, 1e-10)
        assert np.linalg.norm(M @ x - b) <= 1e-8 * np.linalg.norm(b)  # right in every path
        return solver.cg_iterations > before

    assert not attempted(A)  # nothing to try yet
    # A's factor does not solve B in two iterations, nor B's A: the rate drops below one half
    assert attempted(B) and attempted(A)
    assert solver.success_rate < 0.5
    # so the next three solves refactorise at once, and the fourth tries again
    assert [attempted(M) for M in (B, A, B, B)] == [False, False, False, True]
    # the same matrix again: the attempt converges and the rate recovers
    for _ in range(3):
        assert attempted(B)
    assert solver.success_rate > 0.5 and solver.factorizations == 6


def grid_laplacian(n):
    idx = np.arange(n * n).reshape(n, n)
    e = np.concatenate([np.column_stack([idx[:-1].ravel(), idx[1:].ravel()]),
                        np.column_stack([idx[:, :-1].ravel(), idx[:, 1:].ravel()])])
    G = sp.coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(n * n, n * n))
    G = (G + G.T).tocsr()
    X, Y = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    return G, np.column_stack([X.ravel(), Y.ravel()]).astype(float)


def test_nested_dissection_is_a_permutation_that_cuts_fill():
    n = 60
    G, xy = grid_laplacian(n)
    order = nested_dissection(G, xy, leaf=16)
    assert np.array_equal(np.sort(order), np.arange(n * n))
    A = (sp.diags(np.asarray(G.sum(axis=1)).ravel() + 1.0) - G).tocsc()

    def fill(p):
        lu = spla.splu(A[p][:, p].tocsc(), permc_spec="NATURAL", diag_pivot_thresh=0.0)
        return lu.L.nnz + lu.U.nnz

    # row-by-row (banded) order fills about 2 n^3 entries; nested dissection far fewer
    assert fill(order) < 0.5 * fill(np.arange(n * n))


@pytest.mark.parametrize("method", ["nd", "cholesky"])
def test_other_linear_solvers_reach_the_same_shape(method):
    system = small_net(n=9, boundary=True)
    a = relax(system, linear_solver="ldl", rtol=1e-9)
    b = relax(system, linear_solver=method, rtol=1e-9)
    assert a.success and b.success
    assert b.factorizations > 0
    assert np.max(np.abs(a.q - b.q)) < 1e-8
