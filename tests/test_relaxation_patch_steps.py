"""Pseudo-time steps on patches: sweeps around slack fronts; a full step kept, the patch around the
ropes that make it overshoot relaxed from there."""

import numpy as np
import pytest

from shellform.solvers.relaxation import Refinements, energy_change, implicit, nodal_masses, patch_steps, relax
from shellform.solvers.relaxation.line_search import ARMIJO
from shellform.solvers.relaxation.patch import NodeGraph, patchable
from shellform.solvers.relaxation.patch_steps import PatchContext

from test_relaxation import small_net
from test_relaxation_patch import _state


@pytest.fixture
def repairs(monkeypatch):
    """Every repair of a relaxation: its arguments and its outcome."""
    calls = []
    original = patch_steps.repair_full_step

    def recording(ctx, q, p, r1, dE1, slope, h):
        out = original(ctx, q, p, r1, dE1, slope, h)
        # copies: the front sweeps that follow a step move its state and residual in place
        kept = None if out is None else (out[0].copy(), out[1].copy()) + tuple(out[2:])
        calls.append((ctx.system, q.copy(), p.copy(), dE1, slope, kept))
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


def test_a_sweep_lowers_the_potential_moves_only_the_patch_and_keeps_the_residual_exact(monkeypatch):
    system = small_net(n=9)
    q = _state(system)
    monkeypatch.setattr(patch_steps, "FRONT_SHARE", 1.0)  # sweep whatever the share of hot nodes
    graph = NodeGraph(system)
    free = system.free
    st_m = np.repeat(nodal_masses(system), 3)[free]
    st = type("St", (), {"m": st_m, "damping": 0.0})()
    r = system.residual(q)[free]
    q1 = q.copy()
    steps = patch_steps.sweep_fronts(PatchContext(system, graph, st.m, st.damping, system.external_force(), 0.0),
                                     q1, r, 1e3, 0.0)
    assert steps >= 1
    assert energy_change(system, q, q1) < 0
    acc = lambda res: np.linalg.norm((res / st_m).reshape(-1, 3), axis=1).max()
    assert acc(r) < acc(system.residual(q)[free])  # the imbalance it sweeps falls
    assert np.allclose(r, system.residual(q1)[free], rtol=0, atol=1e-9 * np.abs(r).max())
    # the supports are where they were
    assert np.array_equal(q1[system.constrained], q[system.constrained])


def test_relaxation_with_sweeps_reaches_the_same_shape(monkeypatch):
    system = small_net(n=12, EA=1e5)
    plain = relax(system, rtol=1e-9, refinements=Refinements(front_sweeps=False))
    monkeypatch.setattr(patch_steps, "FRONT_SHARE", 0.3)  # a small net's fronts are a large share of it
    swept = relax(system, rtol=1e-9)
    assert plain.success and swept.success, (plain.message, swept.message)
    assert plain.local_steps == 0 and swept.local_steps > 0
    assert np.max(np.abs(swept.q - plain.q)) < 1e-7
    # without the slack-rope active set the sweeps are left out
    assert relax(system, rtol=1e-9, refinements=Refinements(slack_active_set=False)).local_steps == 0


def test_sweeps_are_left_out_where_a_patch_cannot_hold_the_energy():
    from shellform.rods.network import build_rod_system

    from test_implicit_euler import cantilever

    _, rod = cantilever(n=6)
    assert not patchable(build_rod_system(rod))  # bending and twist are not axial members
    assert patchable(small_net(n=4))
