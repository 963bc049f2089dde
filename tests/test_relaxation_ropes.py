"""The ropes' piecewise model of a relaxation step: finite-difference and first-order checks."""

import numpy as np
from fd import fd_gradient, relative_error
from test_axial_effects import random_members

from shellform.effects import Rope
from shellform.solvers.relaxation.ropes import engaged_terms, linearised, stretched_by


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
    grad, vals = engaged_terms(rope, q, engaged)
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
    g_all, _ = engaged_terms(rope, q, ~engaged)
    assert np.allclose(g_all, rope.gradient(q))

    # a step pulling the ends of every member apart by more than its slack stretches the slack ones only
    dq = np.zeros_like(q).reshape(-1, 3)
    apart = 0.3 * length
    for k in np.flatnonzero(engaged)[:2]:
        a, b = conn[k]
        dq[:] = 0.0
        dq[b] = 0.5 * apart[k] * n[k]
        dq[a] = -0.5 * apart[k] * n[k]
        flagged = stretched_by(rope, q, dq.ravel())
        assert flagged[k] and not flagged[~engaged].any()
        assert not stretched_by(rope, q, -dq.ravel())[k]  # pushed together: stays slack


def test_rope_linearised_model_is_the_first_order_change_of_length():
    rng = np.random.default_rng(11)
    nodes, conn = random_members(rng)
    q = nodes.ravel()
    length = np.linalg.norm(nodes[conn[:, 1]] - nodes[conn[:, 0]], axis=1)
    rest = length * np.where(np.arange(len(conn)) % 3 == 0, 1.1, 0.9)
    EA = rng.uniform(1, 5, len(conn))
    rope = Rope(q.size, conn, EA, rest)
    n, gap, k, slack = linearised(rope, q)

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
