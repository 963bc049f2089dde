"""Held measures and the stretch projection of the Newton line search."""

import numpy as np
import pytest
from fd import relative_error

import shellform as sf
from shellform.rods import RodNetwork, RodSection, build_rod_system, stack_polylines
from shellform.rods.statics import solve_incremental
from shellform.solvers.newton import StretchProjection, solve_static
from shellform.validation.cases_rods import G, clamped_stations, straight_rod


def crossing_rods(seed=0, load=0.0):
    """Two rods crossing at a penalty joint, one end of each pinned, a bar and a rope attached."""
    rng = np.random.default_rng(seed)
    x = np.linspace(0.0, 1.0, 6)
    lines = [np.stack([x, 0 * x + 0.4, 0 * x], 1), np.stack([0 * x + 0.4, x, 0 * x], 1)]
    nodes, idx, pairs = stack_polylines(lines, merge=False)
    s = sf.Structure(nodes + 0.02 * rng.normal(size=nodes.shape))
    net = RodNetwork(s)
    for ix in idx:
        net.add_rod(ix, RodSection(EA=1e5, EI=1.0, GJ=0.75))
    net.add_joints(pairs, stiffness_ratio=1e3)
    s.add_bars([[idx[0][-1], idx[1][-1]]], EA=1e4)
    s.add_ropes([[idx[0][-2], idx[1][-2]]], EA=1e4)
    net.pin(0, "start")
    net.pin(1, "start")
    if load:
        s.add_load([idx[0][3], idx[1][3]], [0.0, 0.0, -load])
    system = build_rod_system(net)
    q = system.q_ref + 0.01 * rng.normal(size=system.n_dof)
    return s, system, q


def test_held_measures_and_their_jacobian_match_finite_differences():
    s, system, q = crossing_rods()
    values, J = system.held_measures(q)
    free = system.free

    h = 1e-6
    J_fd = np.zeros((values.size, free.size))
    for j, dof in enumerate(free):
        qp, qm = q.copy(), q.copy()
        qp[dof] += h
        qm[dof] -= h
        J_fd[:, j] = (system.held_measures(qp)[0] - system.held_measures(qm)[0]) / (2 * h)
    assert J.shape == (values.size, free.size)
    assert relative_error(J.toarray(), J_fd) < 1e-8
    # rod edges and the bar (lengths) and the joint gap (three components);
    # the rope is not held, and the edges between pinned nodes depend on no free DOF
    n_lengths = sum(len(e.L) for e in system.effects if e.name in ("rod_stretch", "axial"))
    n_gaps = 3 * sum(len(e.pairs) for e in system.effects if e.name == "joints")
    assert values.size == n_lengths + n_gaps
    rope = next(e for e in system.effects if e.name == "rope")
    assert rope.held_measures(q) is None


def test_a_system_without_stiff_members_holds_nothing():
    s = sf.Structure([[0, 0, 0], [1, 0, 0]])
    s.add_ropes([[0, 1]], EA=1.0)
    s.fix([0])
    s.fix([1], "yz")
    system = sf.build_system(s)
    assert system.held_measures(system.q_ref) is None
    P = StretchProjection(system, system.q_ref, np.ones(system.n_free))
    q_trial = system.q_ref + 0.1
    assert P(q_trial, 1.0) is q_trial


def test_projection_meets_the_linearised_measures_with_a_second_order_correction():
    s, system, q = crossing_rods(1)
    free = system.free
    p = 0.05 * np.random.default_rng(2).normal(size=free.size)
    m0, J = system.held_measures(q)
    P = StretchProjection(system, q, p)
    corrections = []
    for alpha in (0.4, 0.2, 0.1):
        q_trial = q.copy()
        q_trial[free] += alpha * p
        q_proj = P(q_trial, alpha)
        m = system.held_measures(q_proj)[0]
        assert np.max(np.abs(m - (m0 + alpha * (J @ p)))) < 1e-12
        assert np.array_equal(q_proj[system.constrained], q_trial[system.constrained])
        corrections.append(np.linalg.norm(q_proj - q_trial))
    # halving the step quarters the correction: it leaves the slope of the line search alone
    ratios = np.array(corrections[:-1]) / np.array(corrections[1:])
    assert np.allclose(ratios, 4.0, rtol=0.1), ratios
    # joint gaps are linear in q: the projected step keeps them on the straight step
    joints = next(e for e in system.effects if e.name == "joints")
    q_trial = q.copy()
    q_trial[free] += 0.4 * p
    assert np.allclose(joints._gap(P(q_trial, 0.4)), joints._gap(q_trial), atol=1e-12)


def test_projection_gives_the_same_equilibrium():
    results = []
    for project in (False, True):
        s, system, q = crossing_rods(3, load=5.0)
        results.append(solve_static(system, project=project))
    a, b = results
    assert a.success and b.success, (a.message, b.message)
    assert np.abs(b.q[:3 * s.n_nodes]).max() > 0.01  # a visible deflection
    assert np.allclose(a.q, b.q, atol=1e-9)


@pytest.mark.parametrize("axial_ratio", [1e7, 1e9])
def test_axially_stiff_cantilever_in_three_load_steps(axial_ratio):
    """EA L^2 / EI up to 1e9: every load step converges without halving, at the published tip."""
    alpha = 39.24  # reference.CANTILEVER_SELF_WEIGHT: tip (0.2871, -0.8934)
    s, net = straight_rod(clamped_stations(40), EA=axial_ratio, EI=1.0, mass_per_length=alpha / G)
    net.clamp(0, "start")
    s.set_gravity((0.0, 0.0, -G))
    system = build_rod_system(net, gravity_scaled=True)
    res = solve_incremental(system, lam=1.0, n_steps=3)
    assert res.success, res.message
    assert res.n_steps == 3, res.iterations
    tip = res.q[3 * (s.n_nodes - 1): 3 * s.n_nodes]
    assert tip[0] == pytest.approx(0.2871, rel=0.01)
    assert tip[2] == pytest.approx(-0.8934, rel=0.01)


def test_compressed_grid_keeps_the_straight_search_where_it_is_better():
    """Rods pushed into a dome with joints 1e8 times stiffer than the edges: projecting every
    trial (lengths held to the linearisation of compressed, buckling rods) halved the load
    steps twice as often; keeping the better trial gives the straight search's steps."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).parents[1] / "validation" / "rods"))
    from penalty_study import arched_grid

    runs = []
    for project in (False, True):
        s, net, system, idx, pairs = arched_grid(False, 1e8)
        runs.append(solve_incremental(system, mu=1.0, n_steps=10, project=project))
    straight, projected = runs
    assert straight.success and projected.success
    assert projected.n_steps <= straight.n_steps, (projected.iterations, straight.iterations)
    n = 3 * s.n_nodes
    assert np.abs(projected.q[:n] - straight.q[:n]).max() < 1e-7
