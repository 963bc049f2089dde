"""Continuation of a planar rod problem: the post-buckled pinned-pinned elastica.

A straight column of discrete elastic rods under an end load bifurcates at the
Euler load (pi^2 EI / L^2, K = 1); the secondary
branch is the elastica, whose closed form in terms of the complete elliptic
integrals K(m), E(m) with ``m = k^2 = sin^2(alpha / 2)`` (alpha the end slope) is

    P / P_cr = (2 K(m) / pi)^2,   delta / L = 2 k / (pi sqrt(P / P_cr)),
    end shortening / L = 2 - 2 E(m) / K(m).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import brentq, minimize_scalar
from scipy.special import ellipe, ellipk

from shellform.model import Structure
from shellform.rods import RodNetwork, RodSection, build_rod_system
from shellform.solvers.continuation import trace_path
from shellform.solvers.newton import solve_static

N_EDGES, LENGTH, EI = 30, 1.0, 1.0


def planar_column():
    st = np.linspace(0.0, LENGTH, N_EDGES + 1)
    s = Structure(np.stack([st, 0 * st, 0 * st], axis=1))
    net = RodNetwork(s)
    net.add_rod(np.arange(N_EDGES + 1), RodSection(EA=1e6, EI=EI, GJ=EI / 1.3))
    net.pin(0, "start", twist="fixed")
    s.fix([N_EDGES], "yz")
    s.fix(np.arange(N_EDGES + 1), "y")  # bending in the x-z plane only
    s.add_load([N_EDGES], [-1.0, 0, 0])
    return s, build_rod_system(net)


def elastica_ratio(k):
    return (2 * ellipk(k * k) / np.pi) ** 2


def elastica_load_of_deflection(delta):
    """Load ratio P / P_cr of the elastica with midspan deflection ``delta / L``."""
    d = lambda k: 2 * k / (np.pi * np.sqrt(elastica_ratio(k)))  # noqa: E731  (rises to a maximum, then falls)
    k_top = minimize_scalar(lambda k: -d(k), bounds=(0.1, 0.99), method="bounded", options={"xatol": 1e-12}).x
    k = brentq(lambda k: d(k) - delta, 1e-12, k_top, xtol=1e-15)
    return elastica_ratio(k)


def elastica_load_of_shortening(u):
    """Load ratio P / P_cr of the elastica with end shortening ``u / L``."""
    k = brentq(lambda k: 2.0 - 2.0 * ellipe(k * k) / ellipk(k * k) - u, 1e-12, 1 - 1e-12, xtol=1e-15)
    return elastica_ratio(k)


@pytest.fixture(scope="module")
def elastica_run():
    s, system = planar_column()
    res = trace_path(system, "load", initial_increment=1.0, switch_ds=0.01, ds_max=0.06, max_steps=40,
                     on_bifurcation="switch")
    return s, system, res


def test_rod_column_bifurcates_at_the_euler_load(elastica_run):
    s, system, res = elastica_run
    assert res.success, res.message
    bif = res.events[0]
    assert bif.kind == "bifurcation" and bif.located and bif.switched
    P_euler = np.pi**2 * EI / LENGTH**2
    assert abs(bif.parameter - P_euler) / P_euler < 0.01  # discretisation error of 30 edges

    # independent check: where the lowest eigenvalue of the straight column's tangent crosses zero
    def lowest(P):
        st = solve_static(system, lam=P)
        return np.linalg.eigvalsh(system.tangent_free(st.q).toarray())[0]

    P_tangent = brentq(lowest, 0.9 * P_euler, 1.1 * P_euler, xtol=1e-12)
    assert abs(bif.parameter - P_tangent) / P_tangent < 1e-6
    # the critical mode is the half sine wave in z
    nodes_z = bif.mode[2 : 3 * s.n_nodes : 3]
    half_sine = np.sin(np.pi * s.nodes[:, 0] / LENGTH)
    cos = abs(nodes_z @ half_sine) / (np.linalg.norm(nodes_z) * np.linalg.norm(half_sine))
    assert cos > 0.999


def test_rod_elastica_secondary_branch(elastica_run):
    s, system, res = elastica_run
    bif = res.events[0]
    S = np.array(res.states)
    x = S[:, : 3 * s.n_nodes].reshape(len(S), -1, 3)
    on = res["branch"] == 1
    P = res["lam"][on]
    delta = np.abs(x[on, :, 2]).max(axis=1)
    shortening = LENGTH - (x[on, -1, 0] - x[on, 0, 0])
    assert delta.max() > 0.3 * LENGTH  # well into the post-buckling range
    ratio = P / bif.parameter  # against the discrete column's own critical load
    checked = 0
    for r, d, u in zip(ratio, delta, shortening):
        if d < 0.02 * LENGTH:
            continue
        # the load-deflection and load-shortening curves of the elastica, within 1 % in load: the
        # discretisation error of 30 edges (0.6 % at delta = 0.34 L, 0.08 % with 60 edges)
        assert abs(r - elastica_load_of_deflection(d / LENGTH)) < 1e-2, (r, d)
        assert abs(r - elastica_load_of_shortening(u / LENGTH)) < 1e-2, (r, u)
        checked += 1
    assert checked > 10
    # the post-buckled elastica is stable; the straight column past P_cr was not
    assert np.all(res["n_negative"][on] == 0)
    assert bif.n_negative_after == 1
    assert np.all(np.abs(S[:, 1 : 3 * s.n_nodes : 3]) == 0.0)  # stayed in its plane
