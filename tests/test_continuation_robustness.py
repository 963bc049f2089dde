"""Hard cases for the continuation solver: steps onto critical points, stiff members,
clear failures, progress callbacks, checkpoints and resuming."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import all_finite
from test_continuation_models import (
    H, L, LS, P_CR, THETA_CR, braced_critical, braced_truss, load_of_deflection, spring_truss,
    truss_load, von_mises,
)

from shellform import Structure, build_system
from shellform.errors import MechanismError, ModelError
from shellform.io.checkpoint import CheckpointFile
from shellform.solvers.continuation import PathPoint, trace_path

Z_CR = L * np.tan(THETA_CR)


def _past_inversion(pt):
    return pt.q[5] < -0.6 * H


def test_step_landing_exactly_on_the_limit_point():
    """A cylindrical step of exactly the distance to the limit point ends on a singular tangent."""
    system = von_mises("load")
    z0 = 0.45
    q0 = system.q_ref.copy()
    q0[5] = z0
    p0 = truss_load(np.arctan2(z0, L))
    res = trace_path(system, "load", q0=q0, p0=p0, ds=z0 - Z_CR, constraint="cylindrical",
                     max_steps=200, callback=_past_inversion)
    assert res.status == "callback", res.message
    z = np.array(res.states)[:, 5]
    assert abs(z[1] - Z_CR) < 1e-12  # the first step ended on the limit point
    assert all_finite(res["lam"], z)
    assert np.max(np.abs(res["lam"] - truss_load(np.arctan2(z, L)))) < 1e-8 * P_CR
    assert np.all(np.diff(z) < 0)  # kept going down through the limit, no reversal
    limits = res.events_of("limit")
    assert abs(limits[-1].parameter + P_CR) < 1e-9 * P_CR
    assert all(abs(abs(e.parameter) - P_CR) < 1e-9 * P_CR for e in limits)


def test_start_next_to_the_limit_point():
    """A start where the tangent is nearly singular: the path still goes through the limit."""
    system = von_mises("load")
    z0 = Z_CR * (1 + 1e-9)
    q0 = system.q_ref.copy()
    q0[5] = z0
    p0 = truss_load(np.arctan2(z0, L))
    res = trace_path(system, "load", q0=q0, p0=p0, ds=0.01, ds_max=0.02, max_steps=200, callback=_past_inversion)
    assert res.status == "callback", res.message
    z = np.array(res.states)[:, 5]
    assert all_finite(res["lam"])
    assert np.max(np.abs(res["lam"] - truss_load(np.arctan2(z, L)))) < 1e-8 * P_CR
    assert np.all(np.diff(z) < 0)
    assert abs(res.events_of("limit")[-1].parameter + P_CR) < 1e-9 * P_CR


def test_exactly_singular_start_is_a_clear_error():
    # a straight unstressed string loaded transversely: zero transverse stiffness at the start
    s = Structure([[0, 0, 0], [1, 0, 0], [2, 0, 0]])
    s.add_bars([[0, 1], [1, 2]], 1e3)
    s.fix([0, 2])
    s.fix([1], "xy")
    s.add_load([1], [0, 0, -1.0])
    with pytest.raises(MechanismError, match="singular at the starting point") as info:
        trace_path(build_system(s), "load", ds=0.01)
    # the motion is named: node 1 moves alone, transversely
    assert "moving node 1 (1.00)" in str(info.value)


@pytest.mark.parametrize("control", ["load", "displacement"])
def test_very_stiff_member(control):
    """A spring 10^6 times stiffer than the truss bars: same path, no loss of accuracy."""
    system, ks = spring_truss(1e6, control)
    kw = dict(initial_increment=(P_CR if control == "load" else H) / 20, ds_max=0.03, max_steps=300,
              callback=_past_inversion)
    res = trace_path(system, control, **kw)
    assert res.status == "callback", res.message
    S = np.array(res.states)
    v, w = H - S[:, 5], H + LS - S[:, 11]
    P = res["load"]
    assert all_finite(P)
    assert np.max(np.abs(P - load_of_deflection(v))) < 1e-7 * P_CR
    assert np.max(np.abs(w - v - P / ks)) < 1e-12 * H
    if control == "load":
        lim = res.events_of("limit")
        # the rounding of the stiff spring's force (about 1e-3 N here) limits the accuracy
        assert len(lim) == 2 and abs(lim[0].parameter - P_CR) < 1e-6 * P_CR


def test_large_first_step_past_the_bifurcation_no_silent_jump():
    """Steps much longer than the distance to the bifurcation: the primary path is kept."""
    system = braced_truss()
    (Pb, zb), (Pl, zl) = braced_critical()
    res = trace_path(system, "load", initial_increment=0.9 * Pl, max_steps=20, max_displacement=2.0 * H)
    S = np.array(res.states)
    assert np.max(np.abs(S[:, 4])) < 1e-10
    bif = res.events_of("bifurcation")
    assert bif and abs(bif[0].parameter - Pb) / Pb < 1e-6


def test_failure_is_reported_not_hidden():
    """A corrector that cannot converge cuts back to ds_min and reports it; the path so far is kept."""
    system = von_mises("load")
    res = trace_path(system, "load", initial_increment=P_CR / 5, max_iterations=1, ds_min=0.2, max_steps=50)
    assert not res.success and res.status == "failed"
    assert "ds_min" in res.message and "corrector" in res.message
    assert res.rejected_steps > 0
    assert all_finite(res["lam"])
    z = np.array(res.states)[:, 5]
    assert np.max(np.abs(res["lam"] - truss_load(np.arctan2(z, L)))) < 1e-8 * P_CR


def test_bad_input_errors():
    system = von_mises("load")
    with pytest.raises(ModelError, match="displacement control"):
        trace_path(system, "displacement", ds=0.1)
    with pytest.raises(ValueError, match="control"):
        trace_path(system, "time", ds=0.1)
    with pytest.raises(TypeError, match="unknown continuation option"):
        trace_path(system, "load", ds=0.1, step_size=2)
    # no bound, no step and no critical point ahead to take a scale from: a bar pulled along its axis
    s = Structure([[0, 0, 0], [1, 0, 0]])
    s.add_bars([[0, 1]], 1.0)
    s.fix([0])
    s.fix([1], "yz")
    s.add_load([1], [1.0, 0, 0])
    with pytest.raises(ModelError, match="step size"):
        trace_path(build_system(s), "load")
    with pytest.raises(ModelError, match="monitor 'tip'"):
        trace_path(system, "load", ds=0.1, monitors={"tip": 99})
    s = Structure([[0, 0, 0], [1, 0, 0]])
    s.add_bars([[0, 1]], 1.0)
    s.fix([0])
    s.fix([1], "yz")
    with pytest.raises(ModelError, match="no scaled load"):
        trace_path(build_system(s), "load", ds=0.1)


def test_parameter_and_step_bounds():
    system = von_mises("load")
    res = trace_path(system, "load", initial_increment=P_CR / 10, parameter_bounds=(-1.0, 0.5 * P_CR))
    assert res.status == "parameter_bound" and res["lam"][-1] == pytest.approx(0.5 * P_CR, rel=1e-14)
    z = res.states[-1][5]
    assert truss_load(np.arctan2(z, L)) == pytest.approx(0.5 * P_CR, rel=1e-9)
    res = trace_path(system, "load", initial_increment=P_CR / 10, max_steps=3)
    assert res.status == "max_steps" and res.steps == 3 and res.n_points == 4
    res = trace_path(system, "load", initial_increment=P_CR / 10, max_displacement=0.3)
    assert res.status == "displacement_bound" and H - res.states[-1][5] > 0.3
    assert H - res.states[-2][5] <= 0.3


def test_callback_progress_and_monitors():
    system = von_mises("load")
    seen = []

    def progress(pt):
        assert isinstance(pt, PathPoint)
        seen.append((pt.step, pt.lam, pt.monitors["apex_z"], pt.monitors["energy"]))

    res = trace_path(system, "load", initial_increment=P_CR / 10, max_steps=5, callback=progress,
                     monitors={"apex_z": 5, "energy": lambda q, lam, mu: system.energy(q, lam)})
    assert [s[0] for s in seen] == list(range(6))
    assert np.allclose([s[2] for s in seen], res["apex_z"])
    assert np.allclose(res["apex_z"], np.array(res.states)[:, 5] - H)
    assert np.allclose([s[1] for s in seen], res["lam"])


def test_checkpoint_and_resume_reproduce_an_uninterrupted_run(tmp_path):
    system, ks = spring_truss(0.05, "displacement")
    opts = dict(initial_increment=H / 20, ds_max=0.04, max_steps=40)
    full = trace_path(system, "displacement", **opts)
    ck = tmp_path / "path.npz"

    class Crash(Exception):
        pass

    def crash(pt):
        if pt.step == 27:
            raise Crash  # an interruption the solver does not catch

    with pytest.raises(Crash):
        trace_path(system, "displacement", checkpoint=CheckpointFile(ck, every=5), callback=crash, **opts)
    assert ck.exists()
    resumed_from = []
    res = trace_path(system, "displacement", checkpoint=CheckpointFile(ck, every=5, resume=True),
                     callback=lambda pt: resumed_from.append(pt.step), **opts)
    assert resumed_from[0] == 26  # continued after the last checkpoint (step 25), not from the start
    assert res.steps == full.steps and res.n_points == full.n_points
    for col in ("lam", "mu", "load", "displacement", "arc_length", "n_negative", "iterations"):
        assert np.allclose(res[col], full[col], rtol=1e-12, atol=1e-12 * max(1.0, np.abs(full[col]).max())), col
    assert [e.kind for e in res.events] == [e.kind for e in full.events]
    assert np.allclose([e.parameter for e in res.events], [e.parameter for e in full.events], rtol=1e-12)
    assert np.allclose(res.events[0].mode, full.events[0].mode)
    # the states after resuming are those of the uninterrupted run
    # (those before the checkpoint come from it): all of the uninterrupted run's states
    assert res.state_steps == full.state_steps
    assert np.allclose(np.array(res.states), np.array(full.states), atol=1e-12)
    # a checkpoint of another problem is refused
    with pytest.raises(ModelError, match="different problem"):
        trace_path(von_mises("displacement"), "displacement", checkpoint=CheckpointFile(ck, resume=True), **opts)
