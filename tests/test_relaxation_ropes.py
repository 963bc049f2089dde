"""The ropes' piecewise model of a relaxation step: finite-difference and first-order checks."""

import numpy as np
import pytest
from fd import fd_gradient, relative_error
from test_axial_effects import random_members

from shellform.effects import Rope
from shellform.solvers.relaxation.ropes import (engaged_terms, linearised, model_excess, stretched_by,
                                                switch_model_change)


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


def _rope(x_b, rest, EA=1e3):
    """One rope from the origin to ``x_b``, both ends free (6 DOFs)."""
    rope = Rope(6, [[0, 1]], [EA], [rest])
    q = np.concatenate([np.zeros(3), np.asarray(x_b, dtype=float)])
    return rope, q


def _taylor(rope, q, dq):
    """The rope's energy change to second order, from its own gradient and Hessian."""
    rows, cols = rope.hessian_pattern()
    H = np.zeros((6, 6))
    np.add.at(H, (rows, cols), rope.hessian_values(q))
    return float(rope.gradient(q) @ dq + 0.5 * dq @ H @ dq)


def test_a_taut_rope_s_excess_is_its_energy_change_beyond_second_order():
    rope, q = _rope([1.01, 0.0, 0.0], 1.0)
    dq = np.array([0.0, 0.0, 0.0, -0.002, 0.03, 0.01])
    excess = model_excess(rope, q, dq)
    assert excess.shape == (1,)
    actual = rope.energy(q + dq) - rope.energy(q)
    assert excess[0] == pytest.approx(actual - _taylor(rope, q, dq), rel=1e-9, abs=1e-15)
    # what is left is third order in the step
    ratio = model_excess(rope, q, dq)[0] / model_excess(rope, q, dq / 2)[0]
    assert 7.0 < ratio < 9.0


def test_a_nearly_slack_rope_moved_sideways_exceeds_its_model_by_far():
    # strain 1e-5, the step moves one end sideways by 5 % of the length: it stretches the rope
    # by about 1.25e-3, which its tiny tension's geometric stiffness does not foresee; the energy
    # 1/2 k (1e-5 + 1.25e-3)^2 is 63 times the model's 1/2 (k 1e-5) 0.05^2
    rope, q = _rope([1.00001, 0.0, 0.0], 1.0)
    dq = np.array([0.0, 0.0, 0.0, 0.0, 0.05, 0.0])
    excess = model_excess(rope, q, dq)[0]
    model = _taylor(rope, q, dq)
    assert excess == pytest.approx(0.5 * 1e3 * (1e-5 + 1.25e-3) ** 2 - model, rel=2e-3)
    assert excess > 50 * model > 0


def test_slack_ropes_are_modelled_as_their_spring_when_stretched_and_as_nothing_otherwise():
    rope, q = _rope([0.99, 0.0, 0.0], 1.0)
    k = 1e3 / 1.0
    stretch = np.array([0.0, 0.0, 0.0, 0.03, 0.0, 0.0])  # to 1.02: 0.02 past the rest length
    spring = 0.5 * k * (0.99 + 0.03 - 1.0) ** 2
    actual = rope.energy(q + stretch) - rope.energy(q)
    assert model_excess(rope, q, stretch)[0] == pytest.approx(actual - spring, rel=1e-9)
    assert model_excess(rope, q, stretch)[0] == pytest.approx(0.0, abs=1e-9)  # straight: the spring is exact
    # sideways only: slack to first order, but taut after the step
    sideways = np.array([0.0, 0.0, 0.0, 0.0, 0.2, 0.0])
    assert model_excess(rope, q, sideways)[0] == pytest.approx(rope.energy(q + sideways), rel=1e-12)
    assert rope.energy(q + sideways) > 0


def test_the_piecewise_model_differs_from_the_taylor_model_only_for_ropes_the_step_switches():
    k = 1e3
    # a taut rope shortened straight past its rest length: the Taylor model keeps its spring pushing
    taut, q = _rope([1.01, 0.0, 0.0], 1.0)
    shorten = np.array([0.0, 0.0, 0.0, -0.015, 0.0, 0.0])  # to 0.995
    assert switch_model_change(taut, q, shorten)[0] == pytest.approx(-0.5 * k * 0.005**2, rel=1e-9)
    # straight moves: the piecewise model is the rope's energy itself
    actual = taut.energy(q + shorten) - taut.energy(q)
    assert _taylor(taut, q, shorten) + switch_model_change(taut, q, shorten)[0] == pytest.approx(actual, rel=1e-9)
    assert switch_model_change(taut, q, -0.5 * shorten)[0] == 0.0  # still taut
    # a slack rope stretched straight past its rest length: the Taylor model has nothing
    slack, q = _rope([0.99, 0.0, 0.0], 1.0)
    stretch = np.array([0.0, 0.0, 0.0, 0.03, 0.0, 0.0])  # to 1.02
    assert switch_model_change(slack, q, stretch)[0] == pytest.approx(0.5 * k * 0.02**2, rel=1e-9)
    actual = slack.energy(q + stretch) - slack.energy(q)
    assert _taylor(slack, q, stretch) + switch_model_change(slack, q, stretch)[0] == pytest.approx(actual, rel=1e-9)
    assert switch_model_change(slack, q, stretch / 6)[0] == 0.0  # still slack


def test_the_piecewise_model_is_one_formula_for_all_ropes():
    # Taylor model plus the switch term is sum 1/2 k (x)_+^2 - 1/2 k (gap)_+^2 + 1/2 (N / l) (|dd|^2 - (n.dd)^2)
    rng = np.random.default_rng(3)
    ends = rng.normal(size=(40, 3))
    rest = np.linalg.norm(ends, axis=1) * rng.uniform(0.97, 1.03, 40)  # about half of them slack
    n_dof = 3 * 41
    rope = Rope(n_dof, [[0, i + 1] for i in range(40)], np.full(40, 1e3), rest)
    q = np.concatenate([np.zeros(3), ends.ravel()])
    dq = 0.02 * rng.normal(size=n_dof)
    rows, cols = rope.hessian_pattern()
    H = np.zeros((n_dof, n_dof))
    np.add.at(H, (rows, cols), rope.hessian_values(q))
    taylor = float(rope.gradient(q) @ dq + 0.5 * dq @ H @ dq)
    length = np.linalg.norm(ends, axis=1)
    n = ends / length[:, None]
    dd = dq[3:].reshape(-1, 3) - dq[:3]
    gap = length - rest
    x = gap + np.einsum("ij,ij->i", n, dd)
    k = 1e3 / rest
    tension = k * np.maximum(gap, 0.0)
    model = (0.5 * k * (np.maximum(x, 0.0) ** 2 - np.maximum(gap, 0.0) ** 2)
             + 0.5 * tension / length * (np.einsum("ij,ij->i", dd, dd) - np.einsum("ij,ij->i", n, dd) ** 2))
    switched = switch_model_change(rope, q, dq)
    assert 0 < np.count_nonzero(switched) < 40
    assert taylor + switched.sum() == pytest.approx(model.sum(), rel=1e-10)
