"""The closed-form stencil derivatives of the rod hinge effects against the layered dense formulation."""

import numpy as np
import pytest
from rod_hinge_reference import stencil_derivatives
from test_rod_effects import network_from, random_lines

from shellform.effects.rod_hinge import HingeEffect, project_to_edges, stencil_hessian


def hinge_effects(net):
    return [e for e in net.effects() if isinstance(e, HingeEffect)]


def compare(net, q, rtol=1e-11):
    for e in hinge_effects(net):
        energy, g11, H11 = stencil_derivatives(e, q)
        assert e.energy(q) == pytest.approx(float(np.sum(energy)), rel=1e-12, abs=1e-14 * np.abs(energy).sum())
        g = e._stencil_forces(q).T
        H = e.hessian_values(q).reshape(11, 11, -1).transpose(2, 0, 1)
        scale_g = np.abs(g11).max(axis=1, keepdims=True) + 1e-300
        scale_H = np.abs(H11).max(axis=(1, 2), keepdims=True) + 1e-300
        assert np.all(np.abs(g - g11) <= rtol * scale_g), (e.name, np.max(np.abs(g - g11) / scale_g))
        assert np.all(np.abs(H - H11) <= rtol * scale_H), (e.name, np.max(np.abs(H - H11) / scale_H))
        # the global assembly of the same values
        rows, cols = e.hessian_pattern()
        assert rows.size == H.size


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("ratio", [None, "random"])
def test_stencil_derivatives_match_the_layered_formulation(seed, ratio):
    """Curved, twisted, closed, isotropic and anisotropic rods away from their stored frames."""
    rng = np.random.default_rng(seed)
    s, net = network_from(random_lines(rng, (3, 6, 9)), closed=(2,), natural=["rest", "straight", "rest"],
                          twist=[0.3, 0.0, -0.2], seed=seed, ratio=ratio)
    q1 = s.reference_state() + 0.2 * rng.normal(size=s.n_dof)
    net.frames.update(q1)
    q = q1 + 0.3 * rng.normal(size=s.n_dof)
    compare(net, q)


def test_stencil_derivatives_of_straight_rods_with_large_twist():
    x = np.linspace(0, 1, 9)
    line = np.stack([x, 0.2 * x**2, 0 * x], axis=1)
    s, net = network_from([line], natural=["straight"])
    rng = np.random.default_rng(5)
    q = s.reference_state()
    q[3 * s.n_nodes:] = np.linspace(0, 6 * np.pi, s.n_twist)
    q[: 3 * s.n_nodes] += 0.05 * rng.normal(size=3 * s.n_nodes)
    compare(net, q)


def test_cached_tangents_follow_the_state():
    """Two states evaluated alternately (and one changed in place) give each its own derivatives."""
    rng = np.random.default_rng(7)
    s, net = network_from(random_lines(rng, (5, 7)), natural=["rest", "straight"], twist=[0.1, 0.0])
    qa = s.reference_state() + 0.1 * rng.normal(size=s.n_dof)
    qb = qa + 0.1 * rng.normal(size=s.n_dof)
    bend = hinge_effects(net)[0]
    va, vb = bend.hessian_values(qa), bend.hessian_values(qb)
    assert not np.allclose(va, vb)
    assert np.array_equal(bend.hessian_values(qa), va)
    q = qa.copy()
    bend.hessian_values(q)
    q[:] = qb
    assert np.array_equal(bend.hessian_values(q), vb)


def test_projection_and_stencil_expansion_are_the_dense_maps():
    """The general chain rule through the normalisation and the block differences, on random data."""
    from rod_hinge_reference import STENCIL_MAP, to_stencil

    rng = np.random.default_rng(3)
    n = 5
    e0, e1 = rng.normal(size=(2, n, 3))
    l0, l1 = np.linalg.norm(e0, axis=1), np.linalg.norm(e1, axis=1)
    t0, t1 = e0 / l0[:, None], e1 / l1[:, None]
    g = rng.normal(size=(n, 8))
    H = rng.normal(size=(n, 8, 8))
    H = H + H.transpose(0, 2, 1)
    g11, H11 = to_stencil(t0, t1, l0, l1, g, H)
    gz, Hz = project_to_edges(t0.T, t1.T, l0, l1, g.T, H.transpose(1, 2, 0))
    assert np.allclose(gz.T @ STENCIL_MAP, g11, rtol=0, atol=1e-12 * np.abs(g11).max())
    assert np.allclose(stencil_hessian(Hz).transpose(2, 0, 1), H11, rtol=0, atol=1e-12 * np.abs(H11).max())


def test_rod_stretching_values_are_the_bar_values():
    """The component-major Hessian of the rod edges assembles to the bar effect's matrix, on all or some edges."""
    import scipy.sparse as sp

    from shellform.effects.axial import AxialBar

    rng = np.random.default_rng(2)
    s, net = network_from(random_lines(rng, (4, 7)), natural=["rest", "straight"])
    q = s.reference_state() + 0.1 * rng.normal(size=s.n_dof)
    stretch = net.effects()[0]
    bar = AxialBar(stretch.n_dof, stretch.conn, stretch.EA, stretch.L)

    def dense(e):
        return sp.coo_matrix((e.hessian_values(q), e.hessian_pattern()), shape=(q.size, q.size)).toarray()

    A, B = dense(stretch), dense(bar)
    assert np.allclose(A, B, rtol=0, atol=1e-13 * np.abs(B).max())
    members = np.array([1, 4, 5])
    vals = stretch.hessian_values(q)[stretch.hessian_entries(members)].reshape(3, 6, 6)
    assert np.allclose(vals, bar.hessian_values(q).reshape(-1, 6, 6)[members], rtol=0, atol=1e-13 * np.abs(B).max())
    index = np.arange(s.n_nodes)
    sub, sub_bar = stretch.on_members(members, index, s.n_dof), bar.on_members(members, index, s.n_dof)
    assert np.allclose(dense(sub), dense(sub_bar), rtol=0, atol=1e-13 * np.abs(B).max())


def test_shared_patterns_assemble_to_the_sum_of_the_effects():
    """Bending and twisting share one set of triplets in the System; every assembly path sums the effects."""
    import scipy.sparse as sp

    from shellform.rods import build_rod_system

    rng = np.random.default_rng(4)
    s, net = network_from(random_lines(rng, (5, 8)), natural=["rest", "straight"], twist=[0.2, 0.0])
    net.clamp(0, "start")
    net.clamp(1, "start")
    system = build_rod_system(net)
    bend, twist = [e for e in system.effects if isinstance(e, HingeEffect)]
    kb, kt = system.effects.index(bend), system.effects.index(twist)
    assert system._ranges[kb] == system._ranges[kt]
    q = s.reference_state() + 0.05 * rng.normal(size=s.n_dof)

    def dense(e):
        r, c = e.hessian_pattern()
        return sp.coo_matrix((e.hessian_values(q), (r, c)), shape=(q.size, q.size)).toarray()

    total = sum(dense(e) for e in system.effects)
    K = system.tangent(q).toarray()
    assert np.allclose(K, total, rtol=0, atol=1e-13 * np.abs(total).max())
    free = system.free
    assert np.allclose(system.tangent_free(q).toarray(), total[np.ix_(free, free)], rtol=0,
                       atol=1e-13 * np.abs(total).max())
    only_twist = system.assemble_free({twist: twist.hessian_values(q)}).toarray()
    assert np.allclose(only_twist, dense(twist)[np.ix_(free, free)], rtol=0, atol=1e-13 * np.abs(total).max())
    parts = system.assemble_free({bend: bend.hessian_values(q), twist: twist.hessian_values(q)}).toarray()
    both = (dense(bend) + dense(twist))[np.ix_(free, free)]
    assert np.allclose(parts, both, rtol=0, atol=1e-13 * np.abs(total).max())


@pytest.mark.parametrize("ratio", [None, "random"])
def test_compiled_upper_values_are_the_collected_ones(ratio):
    """The compiled hinge kernel against the NumPy collection of the same terms, each effect alone and both."""
    pytest.importorskip("numba")
    from shellform.effects import rod_compiled

    rng = np.random.default_rng(11)
    s, net = network_from(random_lines(rng, (4, 7, 9)), closed=(2,), natural=["rest", "straight", "rest"],
                          twist=[0.3, 0.0, -0.2], seed=3, ratio=ratio)
    q1 = s.reference_state() + 0.2 * rng.normal(size=s.n_dof)
    net.frames.update(q1)
    q = q1 + 0.3 * rng.normal(size=s.n_dof)
    bend, twist = hinge_effects(net)
    assert rod_compiled.available
    for effects in ([bend], [twist], [bend, twist]):
        expected = HingeEffect._hessian(effects, q).upper()
        got = HingeEffect.summed_hessian_upper_values(effects, q).reshape(66, -1)
        scale = np.abs(expected).max(axis=0) + 1e-300
        assert np.all(np.abs(got - expected) <= 1e-12 * scale), [e.name for e in effects]


@pytest.mark.parametrize("natural", [["rest", "straight", "rest"], ["straight"] * 3])
@pytest.mark.parametrize("ratio", [None, "random"])
def test_compiled_energies_and_gradients_are_the_numpy_ones(monkeypatch, ratio, natural):
    """The compiled hinge energies, gradients and force magnitudes against the NumPy form, hinge by hinge, with
    and without natural curvature and anisotropy (whose material-frame terms stay NumPy)."""
    pytest.importorskip("numba")
    from shellform.effects import rod_compiled

    rng = np.random.default_rng(12)
    s, net = network_from(random_lines(rng, (4, 7, 9)), closed=(2,), natural=natural, twist=[0.3, 0.0, -0.2],
                          seed=5, ratio=ratio)
    q1 = s.reference_state() + 0.2 * rng.normal(size=s.n_dof)
    net.frames.update(q1)
    q = q1 + 0.3 * rng.normal(size=s.n_dof)
    assert rod_compiled.available
    for e in hinge_effects(net):
        got = e._compiled_forces(q), e.energy(q), e.gradient(q), e.force_magnitudes(q)
        with monkeypatch.context() as m:
            m.setattr(rod_compiled, "available", False)
            assert e._compiled_forces(q) is None
            expected = e._local(q, 0)[0], e.energy(q), e.gradient(q), e.force_magnitudes(q)
        per_hinge, energy, *vectors = got
        per_hinge0, energy0, *vectors0 = expected
        assert np.all(np.abs(per_hinge - per_hinge0) <= 1e-13 * np.abs(per_hinge0).max()), e.name
        assert energy == pytest.approx(energy0, rel=1e-13), e.name
        for v, v0 in zip(vectors, vectors0):
            assert np.all(np.abs(v - v0) <= 1e-13 * np.abs(v0).max()), e.name


def test_energies_of_the_last_gradient_pass_serve_only_the_same_state():
    """The energy at the point of the last compiled gradient is that pass's; another q, a new stored state or
    another stiffness is evaluated afresh."""
    import copy

    pytest.importorskip("numba")
    rng = np.random.default_rng(3)
    s, net = network_from(random_lines(rng, (5, 8)), natural=["rest", "straight"], twist=[0.2, 0.0], seed=4)
    q = s.reference_state() + 0.1 * rng.normal(size=s.n_dof)
    for e in hinge_effects(net):
        fresh = e.energy(q)
        e.gradient(q)
        assert e.energy(q) == fresh
        assert e.energy(q.copy()) == fresh
        q2 = q.copy()
        q2[3] += 0.1
        assert e.energy(q2) != fresh
        e.gradient(q)
        soft = copy.copy(e)
        soft.k = 0.5 * e.k
        assert soft.energy(q) == pytest.approx(0.5 * fresh, rel=1e-14)
    q1 = q + 0.1 * rng.normal(size=s.n_dof)
    twist = hinge_effects(net)[1]
    twist.gradient(q)
    before = twist.energy(q)
    net.frames.update(q1)  # the energy at q changes with the stored frames (a new chart of the twist)
    changed = twist.energy(q)
    twist._last_forces = None
    assert changed == twist.energy(q)
    assert changed != before


def test_compiled_stretching_is_the_bar(monkeypatch):
    """The compiled energy, gradient and force magnitudes of rod stretching against the bar's NumPy form."""
    pytest.importorskip("numba")
    from shellform.effects import rod_compiled
    from shellform.effects.rod_stretch import RodStretching

    rng = np.random.default_rng(4)
    s, net = network_from(random_lines(rng, (4, 7, 9)), closed=(2,), seed=2)
    q = s.reference_state() + 0.2 * rng.normal(size=s.n_dof)
    stretch = next(e for e in net.effects() if isinstance(e, RodStretching))
    assert stretch._compiled(q) is not None
    got = stretch.energy(q), stretch.gradient(q), stretch.force_magnitudes(q)
    monkeypatch.setattr(rod_compiled, "available", False)
    assert stretch._compiled(q) is None
    expected = stretch.energy(q), stretch.gradient(q), stretch.force_magnitudes(q)
    assert got[0] == pytest.approx(expected[0], rel=1e-13)
    for v, v0 in zip(got[1:], expected[1:]):
        assert np.all(np.abs(v - v0) <= 1e-13 * np.abs(v0).max())


@pytest.mark.parametrize("ratio", [None, "random"])
def test_tangents_with_and_without_the_compiled_hinges(monkeypatch, ratio):
    """The System's tangents with the hinge values added straight into the data equal those summed by the 0/1
    product from the NumPy values (numba absent), and the dense sum of the effects' full Hessians."""
    import scipy.sparse as sp

    from shellform.effects import rod_compiled
    from shellform.rods import build_rod_system

    def tangents(available):
        monkeypatch.setattr(rod_compiled, "available", available)
        rng = np.random.default_rng(8)
        s, net = network_from(random_lines(rng, (5, 8)), natural=["rest", "straight"], twist=[0.2, 0.0], seed=2,
                              ratio=ratio)
        net.clamp(0, "start")
        net.pin(1, "end")
        system = build_rod_system(net)
        q = s.reference_state() + 0.05 * rng.normal(size=s.n_dof)
        net.frames.update(q)
        q = q + 0.05 * rng.normal(size=s.n_dof)
        direct = bool(system._upper_free.direct)
        return system, q, direct, system.tangent_free(q).toarray(), system.tangent(q).toarray()

    system, q, direct, K_free, K = tangents(rod_compiled.njit is not None)
    assert direct == (rod_compiled.njit is not None)
    _, _, direct, K_free0, K0 = tangents(False)
    assert not direct
    total = sum(sp.coo_matrix((e.hessian_values(q), e.hessian_pattern()), shape=(q.size, q.size)).toarray()
                for e in system.effects)
    tol = 1e-13 * np.abs(total).max()
    assert np.allclose(K, total, rtol=0, atol=tol)
    assert np.allclose(K_free, total[np.ix_(system.free, system.free)], rtol=0, atol=tol)
    assert np.allclose(K0, K, rtol=0, atol=tol)
    assert np.allclose(K_free0, K_free, rtol=0, atol=tol)


def test_a_copy_of_the_system_with_other_effects_takes_its_own():
    """A shallow copy of a System with copies of its effects (another axial stiffness) assembles from those,
    also where the effects add their values to the tangent's data themselves."""
    from shellform.rods import build_rod_system
    from shellform.solvers.relaxation.stiffness import with_stiffness_scale

    rng = np.random.default_rng(6)
    s, net = network_from(random_lines(rng, (5, 7)), natural=["rest", "straight"], twist=[0.1, 0.0], seed=1)
    net.clamp(0, "start")
    net.clamp(1, "end")
    system = build_rod_system(net)
    q = s.reference_state() + 0.05 * rng.normal(size=s.n_dof)
    stretch = next(e for e in system.effects if e.name == "rod_stretch")
    K = system.tangent_free(q).toarray()
    K_stretch = system.assemble_free({stretch: stretch.hessian_values(q)}).toarray()
    soft = with_stiffness_scale(system, 1e-3)
    expected = K - K_stretch + soft.assemble_free({e: e.hessian_values(q) for e in soft.effects
                                                   if e.name == "rod_stretch"}).toarray()
    tol = 1e-13 * np.abs(K).max()
    assert np.allclose(soft.tangent_free(q).toarray(), expected, rtol=0, atol=tol)
    assert np.allclose(system.tangent_free(q).toarray(), K, rtol=0, atol=0)
