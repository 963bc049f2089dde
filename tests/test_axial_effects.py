"""Finite-difference checks of the bar, rope and load effects."""

import numpy as np
import pytest
from fd import dense_hessian, fd_gradient, fd_jacobian, relative_error

from shellform.effects import AxialBar, ConstantForce, Rope


def random_members(rng, n_nodes=6, n_members=9):
    nodes = rng.normal(size=(n_nodes, 3))
    conn = np.array([rng.choice(n_nodes, 2, replace=False) for _ in range(n_members)])
    return nodes, conn


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("cls", [AxialBar, Rope])
def test_gradient_and_hessian_match_finite_differences(cls, seed):
    rng = np.random.default_rng(seed)
    nodes, conn = random_members(rng)
    q0 = nodes.ravel()
    length = np.linalg.norm(nodes[conn[:, 1]] - nodes[conn[:, 0]], axis=1)
    # half the members stretched, half compressed: ropes then have taut and slack members
    rest = length * np.where(np.arange(len(conn)) % 2 == 0, 0.8, 1.25)
    eff = cls(q0.size, conn, rng.uniform(1, 5, len(conn)), rest)
    q = q0 + 0.01 * rng.normal(size=q0.size)

    g = eff.gradient(q)
    assert relative_error(g, fd_gradient(eff.energy, q)) < 1e-7
    H = dense_hessian(eff, q)
    assert relative_error(H, fd_jacobian(eff.gradient, q)) < 1e-7
    assert np.allclose(H, H.T)


def test_rope_is_inert_while_slack_and_matches_bar_when_taut():
    nodes = np.array([[0.0, 0, 0], [1.0, 0, 0]])
    q = nodes.ravel()
    slack = Rope(6, [[0, 1]], [10.0], [1.2])
    assert slack.energy(q) == 0.0
    assert np.all(slack.gradient(q) == 0.0)
    assert np.all(slack.hessian_values(q) == 0.0)
    assert slack.member_results(q)["slack"][0] == 1

    taut_rope = Rope(6, [[0, 1]], [10.0], [0.8])
    bar = AxialBar(6, [[0, 1]], [10.0], [0.8])
    assert taut_rope.energy(q) == pytest.approx(bar.energy(q))
    assert np.allclose(taut_rope.gradient(q), bar.gradient(q))
    assert np.allclose(taut_rope.hessian_values(q), bar.hessian_values(q))
    # N = EA (l - L) / L = 10 * 0.2 / 0.8
    assert taut_rope.member_results(q)["axial_force"][0] == pytest.approx(2.5)


def test_bar_carries_compression():
    bar = AxialBar(6, [[0, 1]], [10.0], [1.25])
    q = np.array([0.0, 0, 0, 1.0, 0, 0])
    res = bar.member_results(q)
    assert res["axial_force"][0] == pytest.approx(-2.0)
    assert res["strain"][0] == pytest.approx(-0.2)
    # the compressed bar pushes node b away from node a (+x)
    assert bar.gradient(q)[3] == pytest.approx(-2.0)


def test_constant_force_potential():
    f = np.array([1.0, -2.0, 3.0])
    eff = ConstantForce(f)
    q = np.array([0.3, 0.1, -0.2])
    assert eff.energy(q) == pytest.approx(-f @ q)
    assert np.allclose(eff.gradient(q), -f)
    assert eff.hessian_values(q).size == 0
