"""Cross-sections by shape and the anisotropic bending energy: properties, finite differences, closed forms."""

import numpy as np
import pytest
from fd import dense_hessian
from test_rod_effects import check_effects, network_from, random_lines

from shellform.errors import ModelError
from shellform.model import Structure
from shellform.rods import RestShape, RodNetwork, RodSection, stack_polylines
from shellform.effects.rod_kinematics import curvature_binormal, material_curvatures, material_frames
from shellform.rods.section import circular_section, section_of
from shellform.rods.network import build_rod_system
from shellform.geometry.sections import hollow_circle, rectangle, rectangle_torsion_constant, solid_circle
from shellform.rods.statics import solve_incremental
from shellform.validation.cases_rods import (
    critical_parameter,
    lowest_eigenvalue,
    narrow_cantilever,
    rectangular_cantilever,
    rectangular_cantilever_tip,
)
from shellform.validation.reference import PRANDTL_COEFFICIENT

# -- shapes -------------------------------------------------------------------------------------------


# Saint-Venant's torsion factor beta = J / (a b^3) of an a x b rectangle (a >= b), tabulated by
# Timoshenko and Goodier, Theory of Elasticity (1970), section 109, to three digits
TORSION_BETA = {1.0: 0.141, 1.5: 0.196, 2.0: 0.229, 3.0: 0.263, 4.0: 0.281, 5.0: 0.291, 10.0: 0.312}


@pytest.mark.parametrize("ratio", sorted(TORSION_BETA))
def test_rectangle_torsion_constant_matches_the_tabulated_factor(ratio):
    b = 0.02
    J = rectangle_torsion_constant(ratio * b, b)
    assert J / (ratio * b * b**3) == pytest.approx(TORSION_BETA[ratio], abs=6e-4)
    assert rectangle_torsion_constant(b, ratio * b) == J  # the order of the sides does not matter


def test_thin_rectangle_tends_to_one_third():
    # J -> a b^3 / 3 (1 - 0.630 b / a) for a thin strip
    a, b = 1.0, 1e-3
    assert rectangle_torsion_constant(a, b) == pytest.approx(a * b**3 / 3 * (1 - 0.6302 * b / a), rel=1e-6)


def test_section_properties_are_computed_from_the_dimensions():
    r = rectangle(depth=0.03, width=0.05)
    assert r.area == pytest.approx(1.5e-3)
    assert r.I1 == pytest.approx(0.05 * 0.03**3 / 12) and r.I2 == pytest.approx(0.03 * 0.05**3 / 12)
    assert (r.c1, r.c2) == (0.015, 0.025)
    h = hollow_circle(outer_radius=0.05, thickness=0.01)
    assert h.area == pytest.approx(np.pi * (0.05**2 - 0.04**2))
    assert h.I1 == h.I2 == pytest.approx(np.pi * (0.05**4 - 0.04**4) / 4) and h.J == pytest.approx(2 * h.I1)
    c = solid_circle(0.01)
    sec = section_of(r, E=1e10, G=6e8, density=500.0)
    assert sec.EI == pytest.approx(1e10 * r.I1) and sec.EI2 == pytest.approx(1e10 * r.I2)
    assert sec.GJ == pytest.approx(6e8 * r.J) and sec.mass_per_length == pytest.approx(0.75)
    assert sec.rotational_inertia == pytest.approx(500.0 * (r.I1 + r.I2))
    old, rr = circular_section(E=1e11, G=4e10, radius=0.01, density=1e3), 0.01
    # the numbers of the former formulas, bit for bit
    assert (old.EA, old.EI, old.GJ) == (1e11 * (np.pi * rr**2), 1e11 * (np.pi * rr**4 / 4), 4e10 * (np.pi * rr**4 / 2))
    assert old.rotational_inertia == 1e3 * (np.pi * rr**4 / 2)
    assert old.shape == c
    for bad in (lambda: rectangle(0.0, 1.0), lambda: hollow_circle(0.01, 0.01), lambda: solid_circle(-1.0),
                lambda: section_of(r, E=0.0, G=1.0)):
        with pytest.raises(ModelError):
            bad()


def test_extreme_fibre_stress_of_a_rectangle_and_a_circle():
    r = rectangle(depth=0.2, width=0.1)
    N, M1, M2 = -3.0e3, 2.0e2, -50.0
    corners = [N / r.area + s1 * M1 * r.c1 / r.I1 + s2 * M2 * r.c2 / r.I2 for s1 in (-1, 1) for s2 in (-1, 1)]
    assert r.max_stress(N, M1, M2) == pytest.approx(max(abs(v) for v in corners))
    c = hollow_circle(0.05, 0.005)
    phi = np.linspace(0, 2 * np.pi, 100001)
    ring = N / c.area + (M1 * np.cos(phi) + M2 * np.sin(phi)) * c.c1 / c.I1
    assert c.max_stress(N, M1, M2) == pytest.approx(np.abs(ring).max(), rel=1e-8)


# -- the anisotropic bending energy -------------------------------------------------------------------


def anisotropic_network(lines, closed=(), natural=None, twist=None, seed=0, ratio="random"):
    """Rods with EI1 != EI2 (random, or EI2 = ratio EI1), natural curvature and twist as asked."""
    return network_from(lines, closed=closed, natural=natural, twist=twist, seed=seed, ratio=ratio)


def direct_bending_energy(net, q):
    """``sum_i 1/(4 dl) sum_j sum_k EI_k (omega_k^j - omega_bar_k^j)^2`` from the kinematics."""
    frames = net.frames
    t, _ = frames.tangents(q)
    u = frames.directors(q)
    h0, h1 = frames.hinges.T
    kb = curvature_binormal(t[h0], t[h1])
    theta = q[net.edge_twist]
    EI = np.stack([net.EI, net.EI2], axis=1)
    total = 0.0
    for j, e in enumerate((h0, h1)):
        omega = material_curvatures(kb, *material_frames(u[e], t[e], theta[e]))
        total += np.sum(np.sum(EI * (omega - net.natural_curvature[:, j]) ** 2, axis=1) / (4 * net.voronoi))
    return total


@pytest.mark.parametrize("seed", range(3))
def test_anisotropic_bending_fd_away_from_the_stored_frames(seed):
    """Curved and straight rods (one closed) with natural curvature and twist, far from the stored frames."""
    rng = np.random.default_rng(seed)
    s, net = anisotropic_network(random_lines(rng, (3, 5, 8)), closed=(2,), natural=["rest", "straight", "rest"],
                                 twist=[0.3, 0, -0.2], seed=seed)
    q1 = s.reference_state() + 0.2 * rng.normal(size=s.n_dof)
    net.frames.update(q1)
    q = q1 + 0.2 * rng.normal(size=s.n_dof)
    check_effects(net, q)
    bend = net.effects()[1]
    assert bend.aniso.size == len(net.EI)
    assert bend.energy(q) == pytest.approx(direct_bending_energy(net, q), rel=1e-12)


def test_anisotropic_straight_rod_with_large_twist_and_an_array_curvature():
    x = np.linspace(0, 1, 8)
    line = np.stack([x, 0.1 * np.sin(3 * x), 0 * x], axis=1)
    kappa = np.random.default_rng(4).normal(size=(6, 2))
    s, net = anisotropic_network([line], natural=[kappa], ratio=0.05)
    rng = np.random.default_rng(1)
    q = s.reference_state()
    q[3 * s.n_nodes:] = np.linspace(0, 6 * np.pi, 7)
    q[: 3 * s.n_nodes] += 0.05 * rng.normal(size=3 * s.n_nodes)
    check_effects(net, q)
    assert net.effects()[1].energy(q) == pytest.approx(direct_bending_energy(net, q), rel=1e-12)


def test_anisotropic_exactly_straight_rod_has_no_bending_force():
    x = np.linspace(0, 2, 6)
    s, net = anisotropic_network([np.stack([x, 0.5 * x, 0 * x], axis=1)], natural=["straight"], ratio=10.0)
    q = s.reference_state()
    q[: 3 * s.n_nodes] *= 1.01
    q[3 * s.n_nodes:] = [0.0, 0.1, 0.3, -0.2, 0.4]
    check_effects(net, q)
    assert np.allclose(net.effects()[1].gradient(q), 0.0)


def test_turning_the_section_a_quarter_swaps_the_stiffnesses():
    """A bent straight rod: theta = pi/2 on every edge with (EI1, EI2) = (EI2, EI1) at theta = 0."""
    x = np.linspace(0, 1, 6)
    line = np.stack([x, 0 * x, 0 * x], axis=1)
    bent = np.stack([np.sin(x), 1 - np.cos(x), 0.2 * x**2], axis=1)

    def energy(EI, EI2, theta):
        s = Structure(line)
        net = RodNetwork(s)
        net.add_rod(np.arange(6), RodSection(EA=1.0, EI=EI, GJ=1.0, EI2=EI2), RestShape(natural_curvature="straight"))
        q = s.reference_state()
        q[: 3 * s.n_nodes] = bent.ravel()
        q[3 * s.n_nodes:] = theta
        return net.effects()[1].energy(q)

    assert energy(1.0, 7.0, np.pi / 2) == pytest.approx(energy(7.0, 1.0, 0.0), rel=1e-12)
    assert energy(1.0, 7.0, 0.0) != pytest.approx(energy(7.0, 1.0, 0.0), rel=1e-3)


def test_equal_stiffnesses_give_the_isotropic_numbers_bit_for_bit():
    rng = np.random.default_rng(7)
    lines = random_lines(rng, (5, 7))
    q = None
    results = []
    for EI2 in (None, "same"):
        nodes, idx, _ = stack_polylines(lines)
        s = Structure(nodes)
        net = RodNetwork(s)
        for ix in idx:
            EI = np.linspace(1, 2, len(ix) - 2)
            net.add_rod(ix, RodSection(EA=3.0, EI=EI, GJ=1.0, EI2=None if EI2 is None else EI.copy()))
        q = s.reference_state() + 0.1 * np.random.default_rng(8).normal(size=s.n_dof) if q is None else q
        bend = net.effects()[1]
        assert bend.aniso.size == 0
        results.append((bend.energy(q), bend.gradient(q), dense_hessian(bend, q)))
    for a, b in zip(*results):
        assert np.array_equal(a, b)


# -- closed forms -------------------------------------------------------------------------------------

CANTILEVER = {1.0: (0.9912, -0.1235), 10.0: (0.6564, -0.7002)}  # elastica under self-weight, tip (x, z) / L


@pytest.mark.parametrize("axis", [1, 2])
@pytest.mark.parametrize("alpha", sorted(CANTILEVER))
def test_rectangular_cantilever_follows_the_elastica_of_each_axis(alpha, axis):
    """alpha = rho A g L^3 / EI_axis: the tip matches the elastica with that axis's stiffness (EI1 = 4 EI2)."""
    tip, res = rectangular_cantilever_tip(alpha, axis)
    assert res.success, res.message
    x_ref, z_ref = CANTILEVER[alpha]
    assert tip[0] == pytest.approx(x_ref, rel=0.01)
    assert tip[2] == pytest.approx(z_ref, rel=0.01)
    assert abs(tip[1]) < 1e-12


def test_rectangular_cantilever_moments_use_the_stiffness_of_their_axis():
    """The clamp's moment M = w L^2 / 2 is carried about the loaded axis only; the stress follows."""
    s, net = rectangular_cantilever(1e-3, axis=2)  # nearly linear
    system = build_rod_system(net, gravity_scaled=True)
    res = solve_incremental(system, lam=1.0, n_steps=1)
    bend = [e for e in system.effects if e.name == "rod_bend"][0]
    fields = bend.line_results(res.q).fields
    w = s.nodal_mass().sum() * 9.81 / (s.nodes[-1, 0] - s.nodes[0, 0])  # weight per length
    L = s.nodes[-1, 0]  # from the clamp at x = 0
    x_mid = 0.5 * (s.nodes[1:, 0] + s.nodes[:-1, 0])
    expected = w * (L - x_mid) ** 2 / 2
    inner = slice(1, -1)  # edges with a hinge at both ends
    assert np.allclose(np.abs(fields["bending_moment_2"][inner]), expected[inner], rtol=0.02, atol=1e-3 * expected[1])
    assert np.abs(fields["bending_moment_1"]).max() < 1e-9 * np.abs(fields["bending_moment_2"]).max()
    shape = net._arrays[0].shape
    assert np.allclose(fields["max_stress"][inner], np.abs(fields["bending_moment_2"][inner]) * shape.c2 / shape.I2,
                       rtol=1e-3)


def test_lateral_torsional_buckling_of_a_narrow_cantilever():
    """Prandtl and Michell: P_cr = 4.013 sqrt(EI_min GJ) / L^2 for an end load at the centroid."""
    system, scale = narrow_cantilever()
    P_ref = PRANDTL_COEFFICIENT * scale
    assert lowest_eigenvalue(system, lam=0.9 * P_ref) > 0 > lowest_eigenvalue(system, lam=1.1 * P_ref)
    P = critical_parameter(system, P_ref, "lam")
    assert P == pytest.approx(P_ref, rel=0.01)
