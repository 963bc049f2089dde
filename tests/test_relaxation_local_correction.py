"""The kept factorisation corrected on the rows that changed: region, preconditioner, use in the solver."""

import numpy as np
import pytest

from shellform.solvers.linear import CholeskyFactor
from shellform.solvers.relaxation import Refinements, relax
from shellform.solvers.relaxation.linalg import SPDSolve, diagonal_positions, pcg
from shellform.solvers.relaxation.local_correction import MOST_SHARE, RINGS, LocalCorrection
from shellform.solvers.relaxation.ropes import engaged_terms, is_slack

from test_relaxation import small_net

N = 21


@pytest.fixture(scope="module")
def corner_pulled_taut():
    """A relaxed net's tangent, and the same with the slack ropes of one corner modelled taut."""
    system = small_net(n=N, EA=1e5, boundary=True)
    res = relax(system)
    assert res.success, res.message
    rope = system.effects[0]
    i, j = np.divmod(rope.conn, N)
    corner = (i < N // 3).all(axis=1) & (j < N // 3).all(axis=1)
    engaged = is_slack(rope, res.q) & corner
    assert engaged.sum() >= 10
    K = system.tangent_free(res.q)
    K.sort_indices()
    A0 = K.copy()
    A0.data[diagonal_positions(K)] += 1e-6 * K.diagonal().mean()
    _, values = engaged_terms(rope, res.q, engaged)
    A1 = A0.copy()
    A1.data += system.assemble_free({rope: values}).data
    node_of = np.unique(system.free // 3, return_inverse=True)[1]
    changed_nodes = np.unique(rope.conn[engaged])
    return system, A0, A1, node_of, changed_nodes


def test_region_is_the_changed_nodes_and_their_rings(corner_pulled_taut):
    system, A0, A1, node_of, changed = corner_pulled_taut
    correction = LocalCorrection(A0, node_of)
    assert correction.fits(A1)
    free_node = np.unique(system.free // 3)  # net node of every free node number
    found = free_node[correction.changed_nodes(A1.data, A0.data)]
    # every free end of a rope pulled taut, and nothing else
    assert set(found) == set(changed) & set(free_node)
    rows = correction.region(A1.data, A0.data)
    nodes = free_node[np.unique(node_of[rows])]
    i, j = np.divmod(nodes, N)
    ci, cj = np.divmod(np.asarray(sorted(found)), N)
    # the region reaches RINGS rope steps beyond the changed nodes, not further
    dist = np.min(np.abs(i[:, None] - ci) + np.abs(j[:, None] - cj), axis=1)
    assert dist.max() == RINGS
    assert rows.size < MOST_SHARE * A0.shape[0]


def test_corrected_factor_solves_in_a_few_iterations_what_the_old_one_cannot(corner_pulled_taut):
    _, A0, A1, node_of, _ = corner_pulled_taut
    correction = LocalCorrection(A0, node_of)
    old = CholeskyFactor(A0)
    b = np.random.default_rng(0).standard_normal(A0.shape[0])
    corrected = correction.preconditioner(A1, A0.data, old.solve)
    x, ok, its = pcg(A1, b, corrected, 1e-10, 200)
    assert ok and np.linalg.norm(A1 @ x - b) <= 1e-10 * np.linalg.norm(b)
    _, ok_old, its_old = pcg(A1, b, old.solve, 1e-10, 200)
    assert ok_old
    # each rope pulled taut is an outlying eigenvalue for the old factor alone
    assert its <= 5 and its_old >= its + 4


def test_unchanged_matrix_keeps_the_old_factor_and_a_global_change_asks_for_a_new_one(corner_pulled_taut):
    _, A0, _, node_of, _ = corner_pulled_taut
    correction = LocalCorrection(A0, node_of)
    old = CholeskyFactor(A0)
    assert correction.preconditioner(A0, A0.data, old.solve) == old.solve
    stiffer = A0.copy()
    stiffer.data *= 10.0  # a new stiffness stage: every entry moves
    assert correction.region(stiffer.data, A0.data) is None
    assert correction.preconditioner(stiffer, A0.data, old.solve) is None
    other = A0[:-3, :-3].tocsr()
    assert not correction.fits(other)


def test_solver_reuses_its_factor_across_a_local_change(corner_pulled_taut):
    system, A0, A1, _, _ = corner_pulled_taut
    b = np.random.default_rng(1).standard_normal(A0.shape[0])
    solver = SPDSolve("cholesky", A0.shape[0], cg_max=6, dofs=system.free)
    solver.solve(A0, b, 1e-10)
    x = solver.solve(A1, b, 1e-10)
    assert np.linalg.norm(A1 @ x - b) <= 1e-10 * np.linalg.norm(b)
    assert solver.factorizations == 1 and solver.corrected == 1
    # without the correction the same budget does not reach the tolerance
    plain = SPDSolve("cholesky", A0.shape[0], cg_max=6, dofs=system.free, correct=False)
    plain.solve(A0, b, 1e-10)
    plain.solve(A1, b, 1e-10)
    assert plain.factorizations == 2


def test_relaxation_reaches_the_same_shape_with_and_without_the_correction():
    system = small_net(n=15, EA=1e5, boundary=True)
    with_it = relax(system)
    without = relax(system, refinements=Refinements(factor_correction=False))
    assert with_it.success and without.success
    assert without.corrected_solves == 0
    assert np.abs(with_it.q - without.q).max() < 1e-7
