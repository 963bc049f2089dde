"""The potential of a net on a patch of nodes with the rest held, and the graph that finds the patch."""

import numpy as np
import pytest

from shellform.solvers.relaxation import Refinements, energy_change, relax
from shellform.solvers.relaxation.patch import NodeGraph, Patch
from shellform.solvers.relaxation.ropes import is_slack

from test_relaxation import small_net


def _grid_graph(n):
    return NodeGraph(small_net(n=n, boundary=True))


def test_nodes_within_rings_form_a_diamond_on_a_grid():
    n = 15
    graph = _grid_graph(n)
    centre = (n // 2) * n + n // 2
    for rings in range(5):
        nodes = graph.within([centre], rings)
        i, j = np.divmod(nodes, n)
        assert nodes.size == 2 * rings**2 + 2 * rings + 1
        assert np.all(np.abs(i - n // 2) + np.abs(j - n // 2) <= rings)
    # seeds at a corner: the ball is cut by the edges of the net
    assert graph.within([0], 2).size == 6


def test_members_of_nodes_are_those_with_an_end_among_them():
    system = small_net(n=6, boundary=True)
    graph = NodeGraph(system)
    nodes = np.array([7, 8, 20])
    (members,) = graph.members_of(nodes)
    conn = system.effects[0].conn
    expected = np.flatnonzero(np.isin(conn, nodes).any(axis=1))
    assert np.array_equal(members, expected)


def _state(system, iterations=2):
    """A state part of the way to equilibrium, with slack and taut ropes."""
    res = relax(system, max_iterations=iterations, refinements=Refinements(front_sweeps=False))
    assert not res.success
    rope = system.effects[0]
    slack = is_slack(rope, res.q)
    assert slack.any() and not slack.all()
    return res.q


def test_patch_residual_tangent_and_energy_are_the_whole_net_s_on_the_moving_dofs():
    system = small_net(n=9)
    q = _state(system)
    graph = NodeGraph(system)
    nodes = graph.within([40, 13], 2)
    f_ext = system.external_force()
    patch = Patch(system, graph, nodes, f_ext)
    moving = patch.dofs[patch.moving]
    # the supports among the nodes do not move
    assert set(moving) <= set(system.free)
    assert set(moving // 3) == set(nodes) - set(system.constrained // 3)
    ql = q[patch.dofs]
    r = system.residual(q)
    assert np.allclose(patch.residual(ql), r[moving], rtol=0, atol=1e-12 * np.abs(r).max())
    K = system.tangent(q)[moving][:, moving].toarray()
    assert np.allclose(patch.tangent(ql).toarray(), K, rtol=0, atol=1e-12 * np.abs(K).max())
    rng = np.random.default_rng(3)
    dq = np.zeros(system.n_dof)
    dq[moving] = 1e-2 * rng.standard_normal(moving.size)
    q1 = q + dq
    assert patch.energy_change(ql, q1[patch.dofs]) == pytest.approx(system.energy(q1) - system.energy(q), rel=1e-9)
    assert patch.energy_change(ql, q1[patch.dofs]) == pytest.approx(energy_change(system, q, q1), rel=1e-9)


def test_patch_tangent_matches_finite_differences_of_its_residual():
    system = small_net(n=7)
    q = _state(system)
    graph = NodeGraph(system)
    patch = Patch(system, graph, graph.within([24], 2), system.external_force())
    ql = q[patch.dofs]
    K = patch.tangent(ql).toarray()
    h = 1e-7
    fd = np.empty_like(K)
    for k, dof in enumerate(patch.moving):
        qp, qm = ql.copy(), ql.copy()
        qp[dof] += h
        qm[dof] -= h
        fd[:, k] = (patch.residual(qp) - patch.residual(qm)) / (2 * h)
    assert np.allclose(K, fd, rtol=1e-5, atol=1e-6 * np.abs(K).max())


def test_a_patch_of_axial_members_keeps_their_law():
    system = small_net(n=5)
    rope = system.effects[0]
    keep = np.array([0, 3, 7])
    index = np.full(25, -1)
    ends = np.unique(rope.conn[keep])
    index[ends] = np.arange(ends.size)
    sub = rope.on_members(keep, index, 3 * ends.size)
    q = system.q_ref + 0.05 * np.random.default_rng(0).standard_normal(system.n_dof)
    ql = q[(3 * ends[:, None] + np.arange(3)).ravel()]
    assert type(sub) is type(rope)
    assert np.allclose(sub.member_results(ql)["axial_force"], rope.member_results(q)["axial_force"][keep])
    with pytest.raises(ValueError, match="no new number"):
        rope.on_members(keep, np.full(25, -1), 3)
