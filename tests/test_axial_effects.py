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


def test_slack_rope_stretched_by_a_step_and_its_engaged_model():
    rng = np.random.default_rng(7)
    nodes, conn = random_members(rng)
    q = nodes.ravel()
    length = np.linalg.norm(nodes[conn[:, 1]] - nodes[conn[:, 0]], axis=1)
    rest = length * np.where(np.arange(len(conn)) % 2 == 0, 0.8, 1.25)  # even members taut, odd slack
    EA = rng.uniform(1, 5, len(conn))
    rope = Rope(q.size, conn, EA, rest)

    # the model of an engaged rope is 1/2 (EA / L) (l + n . dd - L)^2: its derivatives at dd = 0
    engaged = np.arange(len(conn)) % 2 == 1
    grad, vals = rope.engaged_terms(q, engaged)
    d = nodes[conn[:, 1]] - nodes[conn[:, 0]]
    n = d / length[:, None]

    def model(qq):
        dd = (qq - q).reshape(-1, 3)
        l_lin = length + np.einsum("ij,ij->i", n, dd[conn[:, 1]] - dd[conn[:, 0]])
        return 0.5 * float(np.sum(np.where(engaged, EA / rest, 0.0) * (l_lin - rest) ** 2))

    assert relative_error(grad, fd_gradient(model, q)) < 1e-7
    rows, cols = rope.hessian_pattern()
    H = np.zeros((q.size, q.size))
    np.add.at(H, (rows, cols), vals)
    # the model is quadratic: central second differences with a large step are exact up to round-off
    h, eye = 1e-2, np.eye(q.size)
    H_fd = np.array([[(model(q + h * (eye[i] + eye[j])) - model(q + h * (eye[i] - eye[j]))
                       - model(q - h * (eye[i] - eye[j])) + model(q - h * (eye[i] + eye[j]))) / (4 * h * h)
                      for j in range(q.size)] for i in range(q.size)])
    assert relative_error(H, H_fd) < 1e-8
    # engaging a taut rope gives its own pull and its axial (not geometric) stiffness
    g_all, _ = rope.engaged_terms(q, ~engaged)
    assert np.allclose(g_all, rope.gradient(q))

    # a step pulling the ends of every member apart by more than its slack stretches the slack ones only
    dq = np.zeros_like(q).reshape(-1, 3)
    apart = 0.3 * length
    for k in np.flatnonzero(engaged)[:2]:
        a, b = conn[k]
        dq[:] = 0.0
        dq[b] = 0.5 * apart[k] * n[k]
        dq[a] = -0.5 * apart[k] * n[k]
        flagged = rope.stretched_by(q, dq.ravel())
        assert flagged[k] and not flagged[~engaged].any()
        assert not rope.stretched_by(q, -dq.ravel())[k]  # pushed together: stays slack


def test_rope_linearised_model_is_the_first_order_change_of_length():
    rng = np.random.default_rng(11)
    nodes, conn = random_members(rng)
    q = nodes.ravel()
    length = np.linalg.norm(nodes[conn[:, 1]] - nodes[conn[:, 0]], axis=1)
    rest = length * np.where(np.arange(len(conn)) % 3 == 0, 1.1, 0.9)
    EA = rng.uniform(1, 5, len(conn))
    rope = Rope(q.size, conn, EA, rest)
    n, gap, k, slack = rope.linearised(q)

    assert np.allclose(np.linalg.norm(n, axis=1), 1.0)
    assert np.allclose(gap, length - rest)
    assert np.allclose(k, EA / rest)
    assert np.array_equal(slack, np.arange(len(conn)) % 3 == 0)
    # gap + n . dd is the stretch after a small step, to second order in the step
    step = rng.normal(size=q.size)
    for h in (1e-3, 1e-4):
        moved = (q + h * step).reshape(-1, 3)
        stretch = np.linalg.norm(moved[conn[:, 1]] - moved[conn[:, 0]], axis=1) - rest
        dd = (h * step).reshape(-1, 3)
        predicted = gap + np.einsum("ij,ij->i", n, dd[conn[:, 1]] - dd[conn[:, 0]])
        assert np.max(np.abs(stretch - predicted)) < 10 * h * h * np.max(np.abs(step)) ** 2 / length.min()
