"""Keeping the full step of the whole net and relaxing the patch around the ropes that make it overshoot."""

import numpy as np
import pytest

from shellform.effects.axial import Rope
from shellform.solvers.relaxation import Refinements, energy_change, implicit, patch_steps, relax
from shellform.solvers.relaxation.line_search import ARMIJO
from shellform.solvers.relaxation.ropes import model_excess, switch_model_change

from test_relaxation import small_net


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


@pytest.fixture
def repairs(monkeypatch):
    """Every repair of a relaxation: its arguments and its outcome."""
    calls = []
    original = patch_steps.repair_full_step

    def recording(system, graph, st, ropes, q, p, r1, dE1, slope, h, f_ext, e_floor):
        out = original(system, graph, st, ropes, q, p, r1, dE1, slope, h, f_ext, e_floor)
        # copies: the front sweeps that follow a step move its state and residual in place
        kept = None if out is None else (out[0].copy(), out[1].copy()) + tuple(out[2:])
        calls.append((system, q.copy(), p.copy(), dE1, slope, kept))
        return out

    monkeypatch.setattr(implicit, "repair_full_step", recording)
    # on a net this small three rings around a rope are a large share of the nodes
    monkeypatch.setattr(patch_steps, "REPAIR_PATCH", 0.5)
    return calls


def test_a_repaired_step_lowers_the_potential_as_reported_and_its_residual_is_exact(repairs):
    system = small_net(n=41, EA=3e5)
    out = relax(system)
    assert out.success
    done = [c for c in repairs if c[5] is not None]
    assert done, "no step was repaired: the test does not exercise the repair"
    assert out.repaired_steps == len(done)
    free = system.free
    for view, q, p, dE1, slope, (q_new, r_new, dE, excess) in done:
        assert dE1 > ARMIJO * slope  # the full step alone would have been cut
        assert dE <= ARMIJO * slope  # the repaired one lowers the potential enough
        assert energy_change(view, q, q_new) == pytest.approx(dE, rel=1e-6, abs=1e-9 * abs(slope))
        r_exact = view.residual(q_new)[free]
        assert np.abs(r_new - r_exact).max() <= 1e-9 * max(np.abs(r_exact).max(), 1.0)
        # outside the patch the state is the full step
        full = q.copy()
        full[free] += p
        changed = np.count_nonzero(q_new != full)
        assert 0 < changed <= patch_steps.REPAIR_PATCH * free.size
        assert excess > 0


def test_relaxation_reaches_the_same_shape_with_and_without_the_repair(repairs):
    system = small_net(n=41, EA=3e5)
    with_it = relax(system)
    assert any(c[5] is not None for c in repairs), "no step was repaired"
    without = relax(system, refinements=Refinements(step_repair=False))
    assert with_it.success and without.success
    assert without.repaired_steps == 0
    assert np.abs(with_it.q - without.q).max() < 1e-7
