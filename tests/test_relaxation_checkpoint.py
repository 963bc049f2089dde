"""Checkpoints of a relaxation: the progress callback sees the state, a restart from it reaches the same shape."""

import numpy as np
import pytest

from shellform import ModelError
from shellform.geometry import rectangle_grid
from shellform.mra import form_find, hanging_net
from shellform.solvers.relaxation import relax

from test_relaxation import chain, small_net


def interrupted(system, scheme, stop_at, **kw):
    """Run until the callback stops it at iteration ``stop_at``; return (result, saved progress)."""
    saved = {}

    def cb(info):
        saved["info"] = info
        return info.iteration >= stop_at

    res = relax(system, scheme=scheme, callback=cb, **kw)
    return res, saved["info"]


def test_progress_carries_copies_of_the_full_state():
    system = small_net(n=5, boundary=True)
    states = []
    relax(system, scheme="implicit", callback=lambda info: states.append(info) and None)
    assert len(states) >= 3
    for info in states:
        assert info.q.shape == (system.n_dof,) and info.v.shape == (system.n_dof,)
        # constrained DOFs stay at their prescribed values, their velocity is zero
        fixed = np.setdiff1d(np.arange(system.n_dof), system.free)
        assert np.array_equal(info.q[fixed], system.q_ref[fixed])
        assert np.all(info.v[fixed] == 0.0)
    # each callback got its own copy (the solver does not overwrite a saved state)
    assert not np.array_equal(states[0].q, states[-1].q)


def test_implicit_restart_from_a_saved_state_reaches_the_same_shape():
    system = small_net(n=7, boundary=True)
    full = relax(system, scheme="implicit", rtol=1e-9)
    assert full.success, full.message
    first, info = interrupted(system, "implicit", stop_at=max(full.iterations // 2, 1), rtol=1e-9)
    assert not first.success and "callback" in first.message
    assert np.array_equal(first.q, info.q)  # the result is the saved state
    # the saved state is part way: neither the start nor the end
    assert np.max(np.abs(info.q - system.q_ref)) > 1e-3 and np.max(np.abs(info.q - full.q)) > 1e-6
    resumed = relax(system, info.q, scheme="implicit", rtol=1e-9)
    assert resumed.success, resumed.message
    assert np.max(np.abs(resumed.q - full.q)) < 1e-7
    assert resumed.iterations < full.iterations + 5


@pytest.mark.parametrize("scheme", ["rk4", "kinetic"])
def test_explicit_restart_with_velocity_continues_the_same_trajectory(scheme):
    system = chain(10, EA=1e4)
    full = relax(system, scheme=scheme, progress_every=50)
    assert full.success, full.message
    stop = 50 * (full.iterations // 100)
    first, info = interrupted(system, scheme, stop_at=stop, progress_every=50)
    assert info.iteration == stop and np.any(info.v != 0.0)
    resumed = relax(system, info.q, v0=info.v, scheme=scheme, progress_every=50)
    assert resumed.success
    # the same steps from the same state: the same end, in the same total number of steps
    assert resumed.iterations + stop == full.iterations
    assert np.max(np.abs(resumed.q - full.q)) < 1e-12 * 10.0
    # restarting from rest instead reaches the same equilibrium by another path
    from_rest = relax(system, info.q, scheme=scheme)
    assert from_rest.success
    assert np.max(np.abs(from_rest.q - full.q)) < 1e-5


def test_form_find_resumes_from_a_saved_state():
    net = hanging_net(rectangle_grid(6.0, 4.0, 6, 4), {"groups": ["corners"]}, slack=0.05)
    full = form_find(net)
    saved = []
    part = form_find(net, callback=lambda info: saved.append(info.q) or info.iteration >= 3)
    assert not part.converged
    resumed = form_find(net, saved[-1])
    assert resumed.converged
    assert np.max(np.abs(resumed.positions - full.positions)) < 1e-6 * 6.0


def test_bad_start_velocity_is_named():
    system = chain(4, EA=1e3)
    with pytest.raises(ModelError, match="v0 must have one value per DOF"):
        relax(system, scheme="rk4", v0=np.zeros(3))
    v = np.zeros(system.n_dof)
    v[4] = np.inf
    with pytest.raises(ModelError, match="DOF 4 \\(node 1\\)"):
        relax(system, scheme="kinetic", v0=v)
