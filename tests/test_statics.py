"""Static equilibrium: assembly consistency, the von Mises truss and the hanging chain."""

import numpy as np
import pytest
from helpers import all_finite
from fd import fd_jacobian, relative_error
from scipy.optimize import brentq

import shellform as sf
from shellform.validation.cases_core import catenary_sag, hanging_chain


def von_mises(L=1.0, H=0.2, EA=1.0e4):
    s = sf.Structure([[-L, 0, 0], [0, 0, H], [L, 0, 0]])
    s.add_bars([[0, 1], [1, 2]], EA=EA)
    s.fix([0, 2])
    s.fix([1], "y")  # planar problem
    s.add_load([1], [0, 0, -1.0])
    return s


def von_mises_load(theta, alpha, EA):
    """Apex load at bar angle theta for the engineering strain measure.

    Bar length L/cos(theta) against rest length L/cos(alpha):
    N = EA (cos(alpha)/cos(theta) - 1), P = -2 N sin(theta).
    """
    return 2 * EA * np.sin(theta) * (1 - np.cos(alpha) / np.cos(theta))


def test_tangent_is_the_derivative_of_the_residual():
    rng = np.random.default_rng(3)
    s = sf.Structure(rng.normal(size=(7, 3)))
    s.add_bars([[0, 1], [1, 2], [2, 3], [3, 0], [1, 3]], EA=5.0)
    s.add_ropes([[3, 4], [4, 5], [5, 6], [6, 0], [2, 5]], EA=3.0, slack=0.05, mass_per_length=2.0)
    s.fix([0])
    s.set_gravity()
    s.add_load([4], [1.0, 2.0, 3.0])
    system = sf.build_system(s)
    q = s.reference_state() + 0.05 * rng.normal(size=s.n_dof)
    K = system.tangent(q).toarray()
    assert relative_error(K, fd_jacobian(system.residual, q)) < 1e-7
    Kff = system.tangent_free(q).toarray()
    assert np.allclose(Kff, K[np.ix_(system.free, system.free)])
    # a matrix from the effects' own values has the tangent's structure entry for entry
    Kt = system.tangent_free(q)
    Ka = system.assemble_free({e: e.hessian_values(q) for e in system.effects})
    assert np.array_equal(Ka.indptr, Kt.indptr) and np.array_equal(Ka.indices, Kt.indices)
    assert np.allclose(Ka.data, Kt.data)
    rope = next(e for e in system.effects if e.name == "rope")
    Kr = system.assemble_free({rope: rope.hessian_values(q)})
    others = system.assemble_free({e: e.hessian_values(q) for e in system.effects if e is not rope})
    assert Kr.nnz == Kt.nnz and np.allclose((Kr + others).toarray(), Kff)


def test_adding_a_few_members_entries_matches_a_whole_assembly():
    rng = np.random.default_rng(5)
    s = sf.Structure(rng.normal(size=(8, 3)))
    s.add_ropes([[0, 1], [1, 2], [2, 3], [3, 4], [4, 5], [5, 6], [6, 7], [7, 0], [1, 5]], EA=3.0, slack=0.05)
    s.add_bars([[0, 4], [2, 6]], EA=5.0)
    s.fix([0, 3])
    system = sf.build_system(s)
    q = s.reference_state() + 0.05 * rng.normal(size=s.n_dof)
    rope = next(e for e in system.effects if e.name == "rope")
    members = np.array([0, 2, 3, 8])  # members 0, 2 and 3 end at held nodes
    vals = np.zeros((len(rope.L), 36))
    vals[members] = rng.normal(size=(members.size, 36))
    # both matrices have the tangent's pattern entry for entry, so their data add
    expected = system.tangent_free(q).data + system.assemble_free({rope: vals.ravel()}).data
    A = system.tangent_free(q)
    system.add_free_entries(A, rope, rope.hessian_entries(members), vals[members].ravel())
    assert np.abs(A.data - system.tangent_free(q).data).max() > 0.1  # the entries of member 8 were added
    assert np.allclose(A.data, expected, rtol=1e-14, atol=1e-14)
    with pytest.raises(sf.ModelError, match="pattern of the free tangent"):
        system.add_free_entries(system.tangent(q), rope, rope.hessian_entries(members), vals[members].ravel())
    with pytest.raises(sf.ModelError, match="Hessian values for"):
        system.assemble_free({rope: vals.ravel()[:-1]})
    other = sf.build_system(s)
    with pytest.raises(sf.ModelError, match="not one of this system's effects"):
        system.add_free_entries(A, other.effects[0], rope.hessian_entries(members), vals[members].ravel())


def test_von_mises_rising_branch_matches_analytic_equilibrium():
    L, H, EA = 1.0, 0.2, 1.0e4
    alpha = np.arctan(H / L)
    system = sf.build_system(von_mises(L, H, EA))
    theta_cr = np.arccos(np.cos(alpha) ** (1 / 3))
    P_cr = 2 * EA * np.sin(theta_cr) ** 3
    q = None
    for frac in (0.2, 0.5, 0.8, 0.95):
        P = frac * P_cr
        res = sf.solve_static(system, q0=q, lam=P)
        assert res.success, res.message
        q = res.q
        # analytic apex height on the rising (pre-limit) branch
        theta = brentq(lambda t: von_mises_load(t, alpha, EA) - P, theta_cr, alpha)
        assert q[5] == pytest.approx(L * np.tan(theta), rel=1e-8)
        # reactions balance the applied load
        R = res.reactions.reshape(-1, 3)
        assert R[:, 2].sum() == pytest.approx(P, rel=1e-8)
        assert R[:, 0].sum() == pytest.approx(0.0, abs=1e-9 * P)
        assert R[0, 0] == pytest.approx(-R[2, 0])


def test_von_mises_beyond_limit_load_fails_clearly_or_jumps_to_inverted_state():
    L, H, EA = 1.0, 0.2, 1.0e4
    alpha = np.arctan(H / L)
    theta_cr = np.arccos(np.cos(alpha) ** (1 / 3))
    P = 1.2 * 2 * EA * np.sin(theta_cr) ** 3
    res = sf.solve_static(sf.build_system(von_mises(L, H, EA)), lam=P)
    assert all_finite(res.q)
    if res.success:
        # the only equilibria at this load are on the inverted branch
        theta = np.arctan(res.q[5] / L)
        assert theta < -alpha
        assert von_mises_load(theta, alpha, EA) == pytest.approx(P, rel=1e-8)


def catenary_chain(span=10.0, length=12.0, n=200):
    """The validation case's chain: equal ropes started 1 % long on a parabola."""
    return hanging_chain(span, length, n)


def test_hanging_chain_sag_matches_catenary():
    span, length = 10.0, 12.0
    s, q0 = catenary_chain(span, length)
    res = sf.solve_static(sf.build_system(s), q0=q0, merit="energy")
    assert res.success, res.message
    a = brentq(lambda a: 2 * a * np.sinh(span / (2 * a)) - length, 0.1, 100.0)
    sag_exact = a * (np.cosh(span / (2 * a)) - 1)
    assert catenary_sag(span, length) == pytest.approx(sag_exact, rel=1e-12)
    sag = -res.q.reshape(-1, 3)[:, 2].min()
    assert abs(sag - sag_exact) / sag_exact < 5e-3
    # and every rope is taut at equilibrium
    forces = sf.build_system(s).member_results(res.q)
    assert not np.any(next(iter(forces.values()))["slack"])


def test_hanging_chain_reactions_carry_its_weight():
    s, q0 = catenary_chain(n=50)
    system = sf.build_system(s)
    res = sf.solve_static(system, q0=q0, merit="energy")
    assert res.success, res.message
    weight = s.nodal_mass().sum() * 9.81
    R = res.reactions.reshape(-1, 3)
    # global balance holds to the accuracy of the free residual the solve reached
    assert abs(R[:, 2].sum() - weight) <= np.sqrt(system.n_free) * res.residual_norm
    assert abs(R[:, 2].sum() - weight) < 1e-6 * weight
    assert R[0, 2] == pytest.approx(R[-1, 2], rel=1e-6)
    assert R[0, 0] == pytest.approx(-R[-1, 0], rel=1e-6)


def test_newton_reports_failure_instead_of_nan():
    s = von_mises()
    system = sf.build_system(s)
    res = sf.solve_static(system, lam=1.0, max_iter=1, rtol=1e-30, atol=0.0)
    assert not res.success
    assert "not converged" in res.message
    assert all_finite(res.q)
