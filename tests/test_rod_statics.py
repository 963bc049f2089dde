"""Static equilibria of single rods with analytic answers: self-weight cantilever, Euler buckling."""

import numpy as np
import pytest
from scipy.optimize import brentq

from shellform.rods.network import build_rod_system
from shellform.rods.statics import solve_incremental
from shellform.solvers.newton import solve_static
from shellform.validation.cases_rods import G, euler_column, self_weight_cantilever

# the elastica under self-weight (shellform.validation.reference.CANTILEVER_SELF_WEIGHT)
CANTILEVER = {1.0: (0.9912, -0.1235), 5.0: (0.8467, -0.4959), 10.0: (0.6564, -0.7002), 39.24: (0.2871, -0.8934)}


@pytest.mark.parametrize("alpha", sorted(CANTILEVER))
def test_self_weight_cantilever_tip_within_one_percent(alpha):
    s, net = self_weight_cantilever(alpha)
    system = build_rod_system(net, gravity_scaled=True)
    res = solve_incremental(system, lam=1.0, n_steps=1 if alpha < 20 else 3)
    assert res.success, res.message
    tip = res.q[3 * (s.n_nodes - 1) : 3 * s.n_nodes]
    x_ref, y_ref = CANTILEVER[alpha]
    assert tip[0] == pytest.approx(x_ref, rel=0.01)
    assert tip[2] == pytest.approx(y_ref, rel=0.01)
    assert abs(tip[1]) < 1e-12  # stays in its plane
    # the clamp carries the whole weight (the rod starts half an edge inside the clamp)
    weight = alpha / G * G * (s.nodes[-1, 0] - s.nodes[0, 0])
    reaction = system.reactions(res.q, 1.0)[: 3 * s.n_nodes].reshape(-1, 3)
    assert reaction[:, 2].sum() == pytest.approx(weight, rel=1e-8)


def test_newton_converges_quadratically_on_a_rod():
    """The exact Hessian shows in the last iterations: |r_{k+1}| <~ C |r_k|^2."""
    s, net = self_weight_cantilever(5.0, n=20)
    system = build_rod_system(net, gravity_scaled=True)
    res = solve_static(system, lam=1.0, rtol=1e-13)
    assert res.success, res.message
    r = np.array(res.residual_norms)
    tail = r[-3:]
    assert tail[-1] < 1e-3 * tail[-2], r
    # order estimate from three consecutive residuals
    order = np.log(tail[2] / tail[1]) / np.log(tail[1] / tail[0])
    assert order > 1.6, r


EULER = {  # P_cr L^2 / EI = pi^2 / K^2
    "pinned-pinned": np.pi**2,
    "clamped-free": np.pi**2 / 4,
    "clamped-pinned": 4.493409457909064**2,  # K = 0.699 (root of tan x = x)
    "clamped-clamped": 4 * np.pi**2,
}


@pytest.mark.parametrize("case", list(EULER))
def test_euler_buckling_load_from_the_tangent(case):
    """The lowest eigenvalue of the free tangent at the compressed straight state crosses zero
    at pi^2 EI / (K L)^2."""
    s, system = euler_column(case)

    def lowest_eigenvalue(P):
        res = solve_static(system, lam=P)
        assert res.success, res.message
        return np.linalg.eigvalsh(system.tangent_free(res.q).toarray())[0]

    P_e = EULER[case]
    assert lowest_eigenvalue(0.9 * P_e) > 0 > lowest_eigenvalue(1.1 * P_e)
    P_cr = brentq(lowest_eigenvalue, 0.9 * P_e, 1.1 * P_e, xtol=1e-9 * P_e)
    assert P_cr == pytest.approx(P_e, rel=0.01)
