"""Discrete elastic rods: kinematics, and finite-difference checks of every rod gradient and Hessian."""

import numpy as np
import pytest
from helpers import all_finite
from fd import dense_hessian, fd_gradient, fd_jacobian

from shellform.errors import MechanismError, ModelError
from shellform.model import Structure
from shellform.effects.rod_kinematics import (
    curvature_binormal,
    normalize,
    parallel_transport,
    signed_angle,
)
from shellform.rods import RestShape, RodNetwork, RodSection, build_rod_system, circular_section, stack_polylines


def network_from(lines, closed=(), natural=None, twist=None, seed=0, ratio=None, **kw):
    """Rods with random stiffnesses; ``ratio``: EI2 = ratio EI (a number) or random ("random"), else isotropic."""
    rng = np.random.default_rng(seed)
    nodes, idx, _ = stack_polylines(lines)
    s = Structure(nodes)
    net = RodNetwork(s)
    for k, ix in enumerate(idx):
        h = len(ix) if k in closed else len(ix) - 2
        EA, EI, GJ = rng.uniform(5, 10), rng.uniform(1, 2, h), rng.uniform(0.5, 1.0)
        EI2 = None if ratio is None else (rng.uniform(0.1, 5, h) if ratio == "random" else ratio * EI)
        net.add_rod(
            ix,
            RodSection(EA=EA, EI=EI, GJ=GJ, EI2=EI2),
            RestShape(natural_curvature=(natural[k] if natural else "rest"), natural_twist=(twist[k] if twist else 0.0)),
            closed=k in closed,
            **kw,
        )
    return s, net


def check_effects(net, q, h=1e-6, tol=1e-6):
    """Finite-difference checks of every effect, with the compiled hinge kernels (where numba is installed) and
    with the NumPy form."""
    from shellform.effects import rod_compiled

    installed = rod_compiled.available
    try:
        for available in {installed, False}:
            rod_compiled.available = available
            _check_effects(net, q, h, tol)
    finally:
        rod_compiled.available = installed


def _check_effects(net, q, h, tol):
    for e in net.effects():
        g = e.gradient(q)
        assert all_finite(g), e.name
        gf = fd_gradient(e.energy, q, h)
        H = dense_hessian(e, q)
        Hf = fd_jacobian(e.gradient, q, h)
        # at an exact minimum of one effect (zero gradient) compare against the
        # Hessian's scale (lengths here are of order one)
        err_g = np.linalg.norm(g - gf) / max(np.linalg.norm(gf), 1e-3 * np.linalg.norm(Hf), 1e-12)
        err_H = np.linalg.norm(H - Hf) / max(np.linalg.norm(Hf), 1e-12)
        assert err_g < tol, (e.name, err_g)
        assert err_H < tol, (e.name, err_H)
        assert np.allclose(H, H.T, rtol=0, atol=1e-12 * np.abs(H).max()), e.name


def random_lines(rng, sizes, step=1.0):
    return [np.cumsum(step * rng.normal(size=(n, 3)), axis=0) + 10 * k for k, n in enumerate(sizes)]


# -- kinematics ------------------------------------------------------------------------------


def test_parallel_transport_is_the_minimal_rotation():
    rng = np.random.default_rng(0)
    a, b, v = (normalize(rng.normal(size=(20, 3))) for _ in range(3))
    Pv = parallel_transport(v, a, b)
    assert np.allclose(parallel_transport(a, a, b), b)
    assert np.allclose(np.linalg.norm(Pv, axis=1), 1.0)
    # the axis a x b is left unchanged and angles are preserved
    axis = np.cross(a, b)
    assert np.allclose(parallel_transport(axis, a, b), axis)
    assert np.allclose(np.einsum("ij,ij->i", Pv, b), np.einsum("ij,ij->i", v, a))


def test_curvature_binormal_length_is_twice_the_half_angle_tangent():
    phi = np.linspace(0.0, 3.0, 7)
    t0 = np.tile([1.0, 0.0, 0.0], (7, 1))
    t1 = np.stack([np.cos(phi), np.sin(phi), 0 * phi], axis=1)
    kb = curvature_binormal(t0, t1)
    assert np.allclose(np.linalg.norm(kb, axis=1), 2 * np.tan(phi / 2))
    assert np.allclose(kb[:, :2], 0.0)


@pytest.mark.parametrize("seed", range(3))
def test_reference_twist_from_holonomy_matches_its_definition(seed):
    """m(q) from the closed form equals the angle between space- and time-parallel frames."""
    rng = np.random.default_rng(seed)
    s, net = network_from(random_lines(rng, (6, 4)), closed=(1,), seed=seed)
    frames = net.frames
    q = s.reference_state()
    for _ in range(4):  # a path of accepted states
        q = q + 0.25 * rng.normal(size=q.size)
        trial = q + 0.25 * rng.normal(size=q.size)
        t, _ = frames.tangents(trial)
        u = frames.directors(trial)
        h0, h1 = frames.hinges.T
        direct = signed_angle(parallel_transport(u[h0], t[h0], t[h1]), u[h1], t[h1])
        closed_form = frames.reference_twist(trial)
        wrapped = np.angle(np.exp(1j * (closed_form - direct)))
        assert np.allclose(wrapped, 0.0, atol=1e-10)
        # accepting a state does not change the energy there
        effects = net.effects()[1:]
        before = [e.energy(q) for e in effects]
        frames.update(q)
        assert np.allclose([e.energy(q) for e in effects], before, rtol=1e-12, atol=1e-14)
        assert np.allclose(np.einsum("ij,ij->i", frames.director, frames.tangent), 0.0, atol=1e-14)


def test_rest_state_is_stress_free_and_energy_matches_material_curvature_form():
    rng = np.random.default_rng(5)
    s, net = network_from(random_lines(rng, (5, 7)), closed=(1,))  # an open rod and a ring
    q = s.reference_state()
    for e in net.effects():
        assert abs(e.energy(q)) < 1e-13
        assert np.allclose(e.gradient(q), 0.0, atol=1e-12)
    # a natural twist rate stresses the twist-free reference frames: E = GJ/(2 dl) (rate dl)^2
    s2, net2 = network_from(random_lines(np.random.default_rng(5), (5, 7)), twist=[0.2, -0.1])
    twist = net2.effects()[2]
    rate = np.concatenate([np.full(3, 0.2), np.full(5, -0.1)])
    expected = np.sum(net2.GJ / (2 * net2.voronoi) * (rate * net2.voronoi) ** 2)
    assert twist.energy(s2.reference_state()) == pytest.approx(expected, rel=1e-10)
    # a deformed state: the bending energy equals 1/4 EI/dl sum_j |omega^j - omega_bar^j|^2
    q = q + 0.1 * rng.normal(size=q.size)
    from test_rod_sections import direct_bending_energy  # (it imports this module's helpers)

    bend = net.effects()[1]
    assert np.array_equal(net.EI2, net.EI)  # isotropic: the two-axis formula with EI1 = EI2
    assert bend.energy(q) == pytest.approx(direct_bending_energy(net, q), rel=1e-12)


# -- finite-difference checks ----------------------------------------------------------------------


@pytest.mark.parametrize("seed", range(3))
def test_curved_twisted_rods_away_from_the_stored_frames(seed):
    """Random curved rods of different lengths (one closed), natural curvature and twist, evaluated
    far from the stored reference state: the transport terms are all active."""
    rng = np.random.default_rng(seed)
    s, net = network_from(
        random_lines(rng, (3, 5, 8)), closed=(2,), natural=["rest", "straight", "rest"], twist=[0.3, 0, -0.2], seed=seed
    )
    q1 = s.reference_state() + 0.2 * rng.normal(size=s.n_dof)
    net.frames.update(q1)
    q = q1 + 0.2 * rng.normal(size=s.n_dof)
    check_effects(net, q)


def test_straight_rod_with_large_twist():
    x = np.linspace(0, 1, 8)
    line = np.stack([x, 0 * x, 0 * x], axis=1)
    s, net = network_from([line], natural=["straight"])
    rng = np.random.default_rng(1)
    q = s.reference_state()
    q[3 * s.n_nodes :] = np.linspace(0, 6 * np.pi, 7)  # three full turns
    q[: 3 * s.n_nodes] += 0.01 * rng.normal(size=3 * s.n_nodes)
    check_effects(net, q)


def test_exactly_straight_rod():
    """kb = 0: no division by the curvature anywhere."""
    x = np.linspace(0, 2, 6)
    line = np.stack([x, 0.5 * x, 0 * x], axis=1)
    s, net = network_from([line], natural=["straight"])
    q = s.reference_state()
    q[: 3 * s.n_nodes] *= 1.01  # stretched along the line: still exactly straight
    q[3 * s.n_nodes :] = [0.0, 0.1, 0.3, -0.2, 0.4]
    check_effects(net, q)
    # straight and untwisted: zero bending gradient
    q[3 * s.n_nodes :] = 0.0
    assert np.allclose(net.effects()[1].gradient(q), 0.0)


@pytest.mark.parametrize("angle", [1e-4, 1e-7])
def test_nearly_collinear_edges(angle):
    x = np.linspace(0, 1, 6)
    line = np.stack([x, angle * np.sin(7 * x), angle * np.cos(5 * x)], axis=1)
    s, net = network_from([line], natural=["rest"], twist=[0.1])
    rng = np.random.default_rng(2)
    q = s.reference_state()
    q[: 3 * s.n_nodes] += angle * rng.normal(size=3 * s.n_nodes)
    q[3 * s.n_nodes :] = 0.05 * rng.normal(size=s.n_twist)
    check_effects(net, q, h=1e-7)


def test_tiny_edge_between_long_ones():
    line = np.array([[0.0, 0, 0], [1.0, 0.1, 0], [1.0 + 1e-4, 0.1, 2e-5], [2.0, 0.3, 0.2], [2.5, 1.0, 0.0]])
    s, net = network_from([line], natural=["rest"])
    rng = np.random.default_rng(3)
    q = s.reference_state()
    q[: 3 * s.n_nodes] += 1e-5 * rng.normal(size=3 * s.n_nodes)
    q[3 * s.n_nodes :] = 0.1 * rng.normal(size=s.n_twist)
    net.frames.update(q)
    q[: 3 * s.n_nodes] += 1e-5 * rng.normal(size=3 * s.n_nodes)
    check_effects(net, q, h=1e-9, tol=1e-5)


def test_sharply_folded_rod():
    """Turning angles up to ~170 degrees."""
    line = np.array([[0.0, 0, 0], [1.0, 0, 0], [0.05, 0.2, 0.0], [0.9, 0.4, 0.1]])
    s, net = network_from([line], natural=["straight"])
    q = s.reference_state()
    q[: 3 * s.n_nodes] *= 0.98
    q[3 * s.n_nodes :] = [0.2, -0.3, 0.5]
    check_effects(net, q, h=1e-7)


# -- builder -------------------------------------------------------------------------------------


def test_builder_allocates_twist_dofs_and_stencils():
    nodes, idx, pairs = stack_polylines(
        [np.array([[0.0, 0, 0], [1, 0, 0], [2, 0, 0]]), np.array([[1.0, -1, 0], [1, 0, 0], [1, 1, 0], [1, 2, 0]])]
    )
    assert pairs.tolist() == [[1, 4]]
    s = Structure(nodes)
    net = RodNetwork(s)
    r0 = net.add_rod(idx[0], circular_section(1e9, 4e8, 1e-3, 1000))
    r1 = net.add_rod(idx[1], circular_section(1e9, 4e8, 1e-3, 1000))
    assert s.n_twist == 2 + 3
    assert list(r0.twist_dofs) == [21, 22] and list(r1.twist_dofs) == [23, 24, 25]
    st = net.hinge_stencils()
    assert st.shape == (3, 11)
    assert list(st[0]) == [0, 1, 2, 3, 4, 5, 6, 7, 8, 21, 22]
    assert np.allclose(net.voronoi, 1.0)
    # the same grid with merged joint nodes
    nodes, idx, pairs = stack_polylines(
        [np.array([[0.0, 0, 0], [1, 0, 0], [2, 0, 0]]), np.array([[1.0, -1, 0], [1, 0, 0], [1, 1, 0], [1, 2, 0]])],
        merge=True,
    )
    assert len(nodes) == 6 and idx[1][1] == 1 and pairs.size == 0


def test_builder_rejects_bad_rods():
    s = Structure(np.array([[0.0, 0, 0], [1, 0, 0], [1, 0, 0], [2, 0, 0]]))
    net = RodNetwork(s)
    with pytest.raises(ModelError, match="out of range"):
        net.add_rod([0, 1, 7], RodSection(EA=1, EI=1, GJ=1))
    with pytest.raises(ModelError, match="zero length"):
        net.add_rod([0, 1, 2, 3], RodSection(EA=1, EI=1, GJ=1))
    with pytest.raises(ModelError, match="EI"):
        net.add_rod([0, 1, 3], RodSection(EA=1, EI=-1.0, GJ=1))
    with pytest.raises(ModelError, match="twice"):
        net.add_rod([0, 1, 0], RodSection(EA=1, EI=1, GJ=1))


def test_free_spinning_rod_is_reported():
    x = np.linspace(0, 1, 5)
    s = Structure(np.stack([x, 0 * x, 0 * x], axis=1))
    net = RodNetwork(s)
    net.add_rod(np.arange(5), RodSection(EA=1, EI=1, GJ=1), name="beam")
    net.pin(0, "start", twist="free")
    net.pin(0, "end", twist="free")
    with pytest.raises(MechanismError, match="beam.*spin"):
        build_rod_system(net)
    net.fix_twist(0, "start")
    build_rod_system(net)
