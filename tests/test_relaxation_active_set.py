"""Settling a step's slack set on the nodes around the ropes whose state the step gets wrong."""

import numpy as np
import pytest

from shellform import Structure, build_system
from shellform.solvers.relaxation import Refinements, active_set, nodal_masses, relax
from shellform.solvers.relaxation.active_set import SlackRopeModel, engage_slack_ropes, settle_slack_set
from shellform.solvers.relaxation.linalg import SPDSolve, diagonal_positions
from shellform.solvers.relaxation.patch import NodeGraph
from shellform.solvers.relaxation.ropes import engaged_terms, is_slack, linearised, rope_effects, stretched_by

from test_relaxation import small_net


@pytest.fixture(scope="module")
def first_step():
    """The first pseudo-time step of a falling net: many slack ropes, a step that stretches some of them."""
    system = small_net(n=21, EA=1e5, boundary=True)
    q = relax(system, max_iterations=1).q
    K = system.tangent_free(q)
    K.sort_indices()
    A = K.copy()
    A.data[diagonal_positions(K)] += np.repeat(nodal_masses(system), 3)[system.free]  # h = 1 s
    r = system.residual(q)[system.free]
    ropes = rope_effects(system)
    return system, ropes, A, r, q


def _stretched(system, ropes, q, p):
    dq = np.zeros(system.n_dof)
    dq[system.free] = p
    return [stretched_by(e, q, dq) for e in ropes]


def _released(system, ropes, q, p):
    """Taut ropes that the step ``p`` (free DOFs) shortens to their rest length or below, to first order."""
    dq = np.zeros(system.n_dof)
    dq[system.free] = p
    out = []
    for e in ropes:
        n, gap, _, slack = linearised(e, q)
        dd = dq[e.dofs[:, 3:]] - dq[e.dofs[:, :3]]
        out.append(~slack & (gap + np.einsum("ij,ij->i", n, dd) <= 0))
    return out


def _model_gradient(system, ropes, A, r, q, p, stretched, released):
    """Gradient at ``p`` of the step's model with the slack ropes of ``stretched`` as springs
    and the taut ropes of ``released`` without theirs."""
    g = A @ p + r
    for e, m, off in zip(ropes, stretched, released):
        for mask, sign in ((m, 1.0), (off, -1.0)):
            ge, values = engaged_terms(e, q, mask)
            g += sign * (ge[system.free] + system.assemble_free({e: values}) @ p)
    return g


def test_settling_on_the_whole_net_minimises_the_step_model(first_step, monkeypatch):
    system, ropes, A, r, q = first_step
    solver = SPDSolve("cholesky", system.free.size)
    # one solve without slack ropes: the step stretches some of them and shortens taut ones
    # below their rest length, where the model's springs push
    p0, _ = engage_slack_ropes(SlackRopeModel(system, ropes, rounds=0), solver, A, r, q, 1e-12, None)
    none = [np.zeros(len(e.L), dtype=bool) for e in ropes]
    assert sum(int(m.sum()) for m in _stretched(system, ropes, q, p0)) >= 10
    assert sum(int(m.sum()) for m in _released(system, ropes, q, p0)) >= 10
    # a patch as large as the net: the local Newton steps solve the step's whole model
    monkeypatch.setattr(active_set, "SETTLE_SHARE", 1.0)
    monkeypatch.setattr(active_set, "SETTLE_RINGS", 100)
    p, sets = settle_slack_set(ropes, NodeGraph(system), A, r, q, p0, none)
    # settled: the step stretches exactly the slack ropes it returns as springs ...
    assert all(np.array_equal(a, b) for a, b in zip(_stretched(system, ropes, q, p), sets))
    # ... and is the minimiser of the convex model, with the taut ropes it releases without springs
    released = _released(system, ropes, q, p)
    assert sum(int(m.sum()) for m in released) >= 1
    g = _model_gradient(system, ropes, A, r, q, p, sets, released)
    assert np.linalg.norm(g) < 1e-8 * np.linalg.norm(r)
    # the model's gradient at the unsettled step is not small: the check can fail
    g0 = _model_gradient(system, ropes, A, r, q, p0, _stretched(system, ropes, q, p0), _released(system, ropes, q, p0))
    assert np.linalg.norm(g0) > 1e-3 * np.linalg.norm(r)


def test_a_patch_beyond_the_share_leaves_the_step_as_it_is(first_step):
    system, ropes, A, r, q = first_step
    solver = SPDSolve("cholesky", system.free.size)
    p0, _ = engage_slack_ropes(SlackRopeModel(system, ropes, rounds=0), solver, A, r, q, 1e-12, None)
    none = [np.zeros(len(e.L), dtype=bool) for e in ropes]
    assert sum(int(m.sum()) for m in _stretched(system, ropes, q, p0)) >= 10  # there is something to settle
    # on this small net three rings around the wrong ropes are more than the share of the nodes
    p, sets = settle_slack_set(ropes, NodeGraph(system), A, r, q, p0, none)
    assert p is p0
    assert all(np.array_equal(a, b) for a, b in zip(_stretched(system, ropes, q, p0), sets))


@pytest.fixture
def settled(monkeypatch):
    """For each settling call of a relaxation, whether it changed the step."""
    changed = []
    original = active_set.settle_slack_set

    def counting(ropes, graph, A, r, q, p, used, geo=None):
        out = original(ropes, graph, A, r, q, p, used, geo)
        changed.append(out[0] is not p)
        return out

    monkeypatch.setattr(active_set, "settle_slack_set", counting)
    # on a net this small three rings around the wrong ropes are a large share of the nodes
    monkeypatch.setattr(active_set, "SETTLE_SHARE", 0.5)
    return changed


def test_relaxation_reaches_the_same_shape_with_and_without_settling(settled):
    system = small_net(n=41, EA=1e5, boundary=True)
    with_it = relax(system)
    assert any(settled), "the relaxation never settled a step: the test does not exercise the settling"
    without = relax(system, refinements=Refinements(slack_settling=False))
    assert with_it.success and without.success
    assert np.abs(with_it.q - without.q).max() < 1e-7


def test_settling_does_not_depend_on_the_front_sweeps(settled):
    system = small_net(n=41, EA=1e5, boundary=True)
    out = relax(system, refinements=Refinements(front_sweeps=False))
    assert out.success
    assert any(settled), "without the front sweeps no step was settled"
    assert out.local_steps == 0  # the sweeps stay off


def line_held_sideways(n=20, gap=1e-12, push=1e-5):
    """A taut line of ``n`` free nodes, each held sideways by a cross rope taut with almost no
    tension, and a push at its first node towards the cross ropes' anchors.

    At rest every cross rope is slack (the line bends towards the anchors along its whole
    length), but with every cross rope as a stiff spring a step only compresses the first
    few: each released rope lets the push reach the next nodes.
    """
    x = np.arange(n + 2, dtype=float)
    line = np.column_stack([x, np.zeros(n + 2), np.zeros(n + 2)])
    anchors = np.column_stack([x[1:-1], np.ones(n), np.zeros(n)])
    s = Structure(np.vstack([line, anchors]))
    s.add_ropes(np.column_stack([np.arange(n + 1), np.arange(1, n + 2)]), EA=1e6, rest_length=0.99)  # 1e4 N
    s.add_ropes(np.column_stack([np.arange(1, n + 1), n + 2 + np.arange(n)]), EA=1e6, rest_length=1.0 - gap)
    s.fix(np.concatenate([[0, n + 1], n + 2 + np.arange(n)]))
    s.add_load([1], [0.0, push, 0.0])
    return build_system(s)


def test_settling_releases_a_chain_of_barely_taut_ropes(monkeypatch):
    n = 60
    system = line_held_sideways(n)
    q = system.q_ref
    K = system.tangent_free(q)
    K.sort_indices()
    A = K.copy()
    A.data[diagonal_positions(K)] += 1e-6 * K.diagonal().mean()
    r = system.residual(q)[system.free]
    ropes = rope_effects(system)
    assert not is_slack(ropes[1], q).any()
    # a patch around the whole chain, so that only the number of local steps limits the settling
    monkeypatch.setattr(active_set, "SETTLE_SHARE", 1.0)
    monkeypatch.setattr(active_set, "SETTLE_RINGS", 2 * n)

    def step():
        solver = SPDSolve("cholesky", system.free.size)
        p, _ = engage_slack_ropes(SlackRopeModel(system, ropes, graph=NodeGraph(system)), solver, A, r, q, 1e-12, None)
        return p, _released(system, ropes, q, p)

    p, released = step()
    assert released[1].all()
    # the step is the minimiser of its model with the whole chain released
    none = [np.zeros(len(e.L), dtype=bool) for e in ropes]
    g = _model_gradient(system, ropes, A, r, q, p, none, released)
    assert np.linalg.norm(g) < 1e-8 * np.linalg.norm(r)
    # the local steps release the chain a few ropes at a time: eight are not enough
    monkeypatch.setattr(active_set, "SETTLE_STEPS", 8)
    _, released = step()
    assert 0 < released[1].sum() < n


def test_slack_active_set_reaches_the_same_shape():
    # a rim-hung net ends with slack ropes along its rim and taut ones inside
    system = small_net(n=9, EA=1e6, boundary=True)
    a = relax(system, rtol=1e-9, refinements=Refinements(slack_active_set=False))
    b = relax(system, rtol=1e-9)
    assert a.success and b.success
    slack = [is_slack(e, b.q) for e in system.effects if e.name == "rope"][0]
    assert slack.any() and not slack.all()
    assert np.max(np.abs(a.q - b.q)) < 1e-8
