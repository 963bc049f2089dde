"""The MRA dynamic-relaxation driver: catenary, agreement of the schemes, failures."""

import numpy as np
import pytest
import scipy.linalg as sla
from scipy.optimize import brentq

from shellform import ModelError, Structure, build_system
from shellform.solvers.relaxation import (
    RelaxationResult,
    node_stiffness_bound,
    nodal_masses,
    relax,
    stable_time_step,
)

SPAN, CHAIN = 10.0, 12.0  # span and chain length [m]
W = 1.0  # weight per length [N/m]


def catenary_parameter(span, length):
    """``a`` of the inextensible catenary: ``length = 2 a sinh(span / 2a)``."""
    return brentq(lambda a: 2 * a * np.sinh(span / (2 * a)) - length, 1e-3 * span, 1e3 * span)


def catenary_sag(span, length):
    a = catenary_parameter(span, length)
    return a * (np.cosh(span / (2 * a)) - 1)


def chain(n, EA):
    """A straight chain of n ropes (slack coefficient 0.2) between two supports at the same height."""
    s = Structure(np.column_stack([np.linspace(0, SPAN, n + 1), np.zeros(n + 1), np.zeros(n + 1)]))
    s.add_ropes(np.column_stack([np.arange(n), np.arange(1, n + 1)]), EA=EA, slack=CHAIN / SPAN - 1,
                mass_per_length=W / 9.81)
    s.fix([0, n])
    s.set_gravity()
    return build_system(s)


def small_net(n=5, EA=2e3, sc=0.08, boundary=False):
    x = np.linspace(0, 4.0, n)
    X, Y = np.meshgrid(x, x, indexing="ij")
    s = Structure(np.column_stack([X.ravel(), Y.ravel(), np.zeros(n * n)]))
    idx = np.arange(n * n).reshape(n, n)
    ropes = np.concatenate([np.column_stack([idx[:-1].ravel(), idx[1:].ravel()]),
                            np.column_stack([idx[:, :-1].ravel(), idx[:, 1:].ravel()])])
    s.add_ropes(ropes, EA=EA, slack=sc, mass_per_length=1.0)
    if boundary:
        s.fix(np.unique(np.concatenate([idx[0], idx[-1], idx[:, 0], idx[:, -1]])))
    else:
        s.fix([idx[0, 0], idx[0, -1], idx[-1, 0], idx[-1, -1], idx[0, n // 2], idx[-1, n // 2]])
    s.set_gravity()
    return build_system(s)


def test_catenary_sag_and_support_forces_fast_scheme():
    system = chain(100, EA=1e7)
    res = relax(system, scheme="implicit")
    assert isinstance(res, RelaxationResult)
    assert res.success, res.message
    sag = -res.q[2::3].min()
    exact = catenary_sag(SPAN, CHAIN)
    assert abs(sag - exact) / exact < 5e-3
    # support forces: half the weight up at each end, horizontal pull w * a
    R = res.reactions.reshape(-1, 3)
    a = catenary_parameter(SPAN, CHAIN)
    assert R[0, 2] == pytest.approx(0.5 * W * CHAIN, rel=1e-6)  # supports carry the whole weight
    assert R[0, 0] == pytest.approx(-W * a, rel=5e-3)  # and pull the chain apart with H = w a
    assert res.max_velocity <= res.velocity_tol and res.max_acceleration <= res.acceleration_tol
    assert np.all(np.isfinite(res.q))


@pytest.mark.parametrize("scheme", ["rk4", "kinetic"])
def test_explicit_schemes_reach_the_catenary_and_the_same_shape(scheme):
    system = chain(20, EA=1e4)
    ref = relax(system, scheme="implicit")
    res = relax(system, scheme=scheme)
    assert res.success, res.message
    exact = catenary_sag(SPAN, CHAIN)
    assert abs(-res.q[2::3].min() - exact) / exact < 5e-3
    # same equilibrium as the implicit scheme, node by node
    assert np.max(np.abs(res.q - ref.q)) < 1e-6 * SPAN
    assert res.iterations > 100 * ref.iterations  # the explicit schemes need many small steps


def test_rk4_stops_on_velocity_and_acceleration():
    system = chain(10, EA=1e3)
    res = relax(system, scheme="rk4", velocity_tol=1e-4, acceleration_tol=1e-3)
    assert res.success
    m = np.repeat(nodal_masses(system), 3)[system.free]
    out_of_balance = -system.residual(res.q)[system.free] / m  # acceleration without the damping term
    damping = 2 * np.sqrt(9.81 / SPAN)  # the default viscous damping per unit mass
    assert np.max(np.linalg.norm(out_of_balance.reshape(-1, 3), axis=1)) <= 1e-3 + damping * 1e-4
    assert np.max(np.linalg.norm(res.v.reshape(-1, 3), axis=1)) <= 1e-4


def test_schemes_agree_on_a_net_with_slack_ropes():
    system = small_net(n=7, boundary=True)
    ref = relax(system, scheme="implicit", rtol=1e-8)
    kin = relax(system, scheme="kinetic", rtol=1e-8)
    assert ref.success and kin.success
    assert np.max(np.abs(kin.q - ref.q)) < 1e-6
    slack = system.member_results(ref.q)
    assert sum(int(v["slack"].sum()) for v in slack.values()) > 0  # a case with slack ropes


def test_stable_time_step_bounds_the_highest_frequency():
    system = small_net(n=4)
    q = relax(system, scheme="implicit").q
    K = system.tangent_free(q).toarray()
    m = np.repeat(nodal_masses(system), 3)[system.free]
    lam = sla.eigh(K, np.diag(m), eigvals_only=True)
    S = node_stiffness_bound(system, q)
    assert np.sqrt(lam.max()) <= np.sqrt(np.max(S / nodal_masses(system)))
    h = stable_time_step(system, q)
    assert h * np.sqrt(lam.max()) < 2.8


def test_too_large_time_step_fails_cleanly():
    system = chain(10, EA=1e4)
    h = stable_time_step(system)
    res = relax(system, scheme="rk4", dt=20 * h, max_iterations=20000)
    assert not res.success
    assert "diverged" in res.message
    assert np.all(np.isfinite(res.q))


def test_iteration_limit_reports_failure_with_finite_state():
    system = chain(10, EA=1e4)
    for scheme in ("rk4", "kinetic", "implicit"):
        res = relax(system, scheme=scheme, max_iterations=3)
        assert not res.success
        assert "not converged" in res.message
        assert np.all(np.isfinite(res.q)) and np.isfinite(res.max_acceleration)


def test_progress_callback_sees_iterations_and_can_stop():
    system = chain(10, EA=1e4)
    seen = []

    def cb(info):
        seen.append(info.iteration)
        return info.iteration >= 200

    res = relax(system, scheme="rk4", callback=cb, progress_every=100)
    assert seen[:3] == [0, 100, 200]
    assert not res.success and "callback" in res.message
    assert res.history["iteration"][:3] == [0, 100, 200]


def test_time_spent_before_counts_against_the_wall_time_limit():
    system = chain(10, EA=1e4)
    free = relax(system, scheme="implicit")
    assert free.success and free.wall_time_s < 100.0  # far below the limit below
    res = relax(system, scheme="implicit", max_wall_time=100.0, spent_s=100.0)
    assert not res.success and "wall-time limit of 100 s" in res.message
    assert res.iterations == 1 and res.wall_time_s >= 100.0
    with pytest.raises(ModelError, match="spent_s"):
        relax(system, spent_s=-1.0)


def test_bad_input_is_named():
    s = Structure([[0, 0, 0], [1, 0, 0], [2, 0, 0]])
    s.add_ropes([[0, 1], [1, 2]], EA=1e3, slack=0.1)  # ropes without mass
    s.fix([0, 2])
    s.add_load([1], [0, 0, -1.0])
    system = build_system(s)
    with pytest.raises(ModelError, match="node 1 has no mass"):
        relax(system, scheme="rk4")
    res = relax(system, scheme="implicit", extra_mass=0.1)  # extra inertia makes it a valid MRA net
    assert res.success
    with pytest.raises(ModelError, match="unknown scheme"):
        relax(system, scheme="euler", extra_mass=0.1)
    with pytest.raises(ModelError, match="non-finite"):
        relax(system, np.full(9, np.nan), extra_mass=0.1)


def test_a_relaxation_takes_the_same_path_whatever_the_clock_says(monkeypatch):
    import time

    system = small_net(n=21, EA=3e5)
    first = relax(system)
    rng = np.random.default_rng(0)
    clock = iter(np.cumsum(rng.uniform(1e-4, 1.0, 100_000)))
    monkeypatch.setattr(time, "perf_counter", lambda: float(next(clock)))
    second = relax(system)
    assert first.success and second.success
    assert (first.iterations, first.factorizations, first.linear_iterations) == (
        second.iterations, second.factorizations, second.linear_iterations)
    assert np.array_equal(first.q, second.q)
