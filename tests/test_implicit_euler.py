"""Implicit Euler with Newton iterations: known answers for oscillators, rods and relaxation."""

import numpy as np
import pytest

from shellform.assembly import build_system
from shellform.errors import ModelError
from shellform.model import Structure
from shellform.rods import NodePath, RodNetwork, RodSection, build_rod_system
from shellform.solvers.implicit_euler import implicit_euler, lumped_mass, relax_to_rest
from shellform.solvers.newton import solve_static


def oscillator(EA=4.0, L=1.0, m=2.0):
    s = Structure([[0.0, 0, 0], [L, 0, 0]])
    s.add_bars([[0, 1]], EA=EA)
    s.fix([0])
    s.fix([1], "yz")
    s.add_point_mass([1], m)
    return s


@pytest.mark.parametrize("c", [0.0, 0.7])
def test_spring_mass_follows_the_implicit_euler_recurrence(c):
    """A bar along x is an exactly linear spring: the scheme must reproduce
    u_{k+1} = ((1 + c h) u_k + h v_k) / (1 + c h + h^2 w^2)."""
    EA, L, m = 4.0, 1.0, 2.0
    s = oscillator(EA, L, m)
    system = build_system(s)
    w2 = EA / L / m
    h, n = 0.05, 60
    q0 = s.reference_state()
    q0[3] += 0.3
    res = implicit_euler(system, h, n * h, q0=q0, damping=c, rtol=1e-13)
    assert res.success, res.message
    u, v = 0.3, 0.0
    for _ in range(n):
        u_new = ((1 + c * h) * u + h * v) / (1 + c * h + h * h * w2)
        v = (u_new - u) / h
        u = u_new
    assert res.q[3] - L == pytest.approx(u, rel=1e-9, abs=1e-13)
    assert res.v[3] == pytest.approx(v, rel=1e-9, abs=1e-13)
    assert res.steps == n and max(res.newton_iterations) <= 2  # linear: one Newton step


def test_last_step_takes_the_remainder_not_a_sliver():
    """300 steps of 0.01 s add up to 3 - 2e-14 s: the last step takes the remainder, and no
    step of 2e-14 s follows (its inertia terms M / dt^2 would drown every force)."""
    s = oscillator()
    q0 = s.reference_state()
    q0[3] += 0.3
    res = implicit_euler(build_system(s), 0.01, 3.0, q0=q0, damping=0.5)
    assert res.success, res.message
    assert res.steps == 300 and res.rejected_steps == 0
    assert res.t == pytest.approx(3.0, abs=1e-12)


def test_first_step_grows_back_to_the_time_step():
    """A small first step doubles step by step up to h; the times are those steps' sums."""
    s = oscillator()
    q0 = s.reference_state()
    q0[3] += 0.3
    res = implicit_euler(build_system(s), 0.08, 0.8, q0=q0, damping=0.5, first_step=0.01)
    assert res.success, res.message
    assert np.diff(np.concatenate([[0.0], res.times]))[:5] == pytest.approx([0.01, 0.02, 0.04, 0.08, 0.08])
    with pytest.raises(ModelError, match="first_step"):
        implicit_euler(build_system(s), 0.08, 0.8, q0=q0, first_step=0.0)


def test_a_rejected_step_holds_the_reduced_size(monkeypatch):
    """After a failed step the halved size is kept for hold_after_reject accepted steps."""
    import shellform.solvers.implicit_euler as ie

    step = ie.Stepper.step
    calls = []

    def fail_first(self, q, v, t, h):
        calls.append(h)
        if len(calls) == 1:
            return None, "forced failure", 0
        return step(self, q, v, t, h)

    monkeypatch.setattr(ie.Stepper, "step", fail_first)
    s = oscillator()
    q0 = s.reference_state()
    q0[3] += 0.3
    res = implicit_euler(build_system(s), 0.08, 0.8, q0=q0, damping=0.5, hold_after_reject=2)
    assert res.success and res.rejected_steps == 1
    assert calls[:6] == pytest.approx([0.08, 0.04, 0.04, 0.04, 0.08, 0.08])


def test_first_order_convergence_to_the_exact_oscillation():
    s = oscillator()
    system = build_system(s)
    w = np.sqrt(4.0 / 2.0)
    T = 2.0
    q0 = s.reference_state()
    q0[3] += 0.1
    errors = []
    for h in (0.02, 0.01, 0.005):
        res = implicit_euler(system, h, T, q0=q0, rtol=1e-13)
        errors.append(abs(res.q[3] - 1.0 - 0.1 * np.cos(w * T)))
    assert errors[0] / errors[1] == pytest.approx(2.0, rel=0.1)
    assert errors[1] / errors[2] == pytest.approx(2.0, rel=0.1)


def cantilever(n=20, L=1.0, EI=1.0, rho_A=1.0, alpha=None):
    l = L / (n - 0.5)
    st = (np.arange(n + 1) - 0.5) * l
    s = Structure(np.stack([st, 0 * st, 0 * st], axis=1))
    net = RodNetwork(s)
    mpl = rho_A if alpha is None else alpha * EI / (9.81 * L**3)
    net.add_rod(np.arange(n + 1), RodSection(EA=1e4, EI=EI, GJ=EI / 1.3, mass_per_length=mpl,
                                          rotational_inertia=1e-4 * mpl))
    net.clamp(0, "start")
    return s, net


def test_free_vibration_period_of_a_cantilever():
    """Small tip deflection released from rest: period 2 pi / w1, w1 = 1.8751^2 sqrt(EI / (rho A L^4))."""
    s, net = cantilever(n=20)
    system = build_rod_system(net)
    w1 = 1.8751041**2
    T1 = 2 * np.pi / w1
    # start from the static shape under a small tip load
    s2, net2 = cantilever(n=20)
    s2.add_load([s2.n_nodes - 1], [0.0, 0.0, -1e-4])
    q0 = solve_static(build_rod_system(net2), lam=1.0).q
    h = T1 / 200
    res = implicit_euler(system, h, 2.3 * T1, q0=q0, mass=lumped_mass(s, net), save_every=1)
    assert res.success, res.message
    t = np.array([st[0] for st in res.states])
    z = np.array([st[1][3 * (s.n_nodes - 1) + 2] for st in res.states])
    # upward zero crossings of the tip, interpolated
    k = np.flatnonzero((z[:-1] < 0) & (z[1:] >= 0))
    crossings = t[k] - z[k] * (t[k + 1] - t[k]) / (z[k + 1] - z[k])
    assert len(crossings) >= 2
    period = np.diff(crossings).mean()
    assert period == pytest.approx(T1, rel=0.01)


def test_dynamic_relaxation_reaches_the_static_equilibrium():
    s, net = cantilever(n=16, alpha=10.0)
    s.set_gravity((0.0, 0.0, -9.81))
    system = build_rod_system(net)
    static = solve_static(system)
    assert static.success
    net.frames.__init__(s.n_nodes, net.edges, net.hinge_edges, s.reference_state(), net.frames.director)
    s_b, net_b = cantilever(n=16, alpha=10.0)
    s_b.set_gravity((0.0, 0.0, -9.81))
    system_b = build_rod_system(net_b)
    # critical damping of the first mode is about 2 w1 = 7 / s (per unit rho A)
    res = relax_to_rest(system_b, h=0.02, damping=5.0, t_max=50.0, mass=lumped_mass(s_b, net_b), force_tol=1e-9)
    assert res.success, res.message
    assert np.allclose(res.q[: 3 * s.n_nodes], static.q[: 3 * s.n_nodes], atol=1e-7)
    assert max(res.newton_iterations) <= 10


def test_rod_carried_rigidly_along_a_path_stays_unstressed():
    """One end pinned, the other moved around a quarter circle: a rigid rotation, so with the
    frames carried by time-parallel transport neither bending nor twist appears, although the
    twist angles of both end edges are held."""
    n, L = 10, 1.0
    x = np.linspace(0, L, n + 1)
    s = Structure(np.stack([x, 0 * x, 0 * x], axis=1))
    net = RodNetwork(s)
    net.add_rod(np.arange(n + 1), RodSection(EA=1e3, EI=1.0, GJ=0.8))
    net.pin(0, "start", twist="fixed")
    net.fix_twist(0, "end")  # the far end's position follows the path

    def tip(t):  # from +x towards +z and on to +y: two great-circle arcs
        a = 0.5 * np.pi * min(t, 1.0)
        b = 0.5 * np.pi * min(max(t - 1.0, 0.0), 1.0)
        return L * np.array([np.cos(a) * np.cos(b), np.sin(b), np.sin(a) * np.cos(b)])[None, :]

    path = NodePath.curve(s, [n], tip)
    system = build_rod_system(net)
    res = implicit_euler(system, 0.05, 2.0, mass=np.zeros(s.n_dof), paths=[path])
    assert res.success, res.message
    X = res.q[: 3 * s.n_nodes].reshape(-1, 3)
    assert np.allclose(X[-1], [0.0, L, 0.0], atol=1e-12)
    assert np.allclose(X, np.outer(x, [0.0, 1.0, 0.0]), atol=1e-9)
    for e in system.effects:
        assert abs(e.energy(res.q)) < 1e-14, e.name


def test_bad_time_step_is_reported():
    system = build_system(oscillator())
    with pytest.raises(ModelError, match="time step"):
        implicit_euler(system, -0.1, 1.0)


def test_a_step_that_meets_its_tolerance_assembles_no_tangent():
    """One tangent per Newton iteration, and none to find that the last one converged."""
    s = oscillator()
    system = build_system(s)
    calls = []
    tangent_free = system.tangent_free
    system.tangent_free = lambda q: calls.append(1) or tangent_free(q)
    q0 = s.reference_state()
    q0[3] += 0.3
    res = implicit_euler(system, 0.01, 0.5, q0=q0, damping=0.5, keep_factor=False)
    assert res.success and res.rejected_steps == 0
    assert len(calls) == sum(max(k, 1) for k in res.newton_iterations)
    # with the kept factor a linear spring needs no tangent after the first step's
    calls.clear()
    kept = implicit_euler(system, 0.01, 0.5, q0=q0, damping=0.5)
    assert kept.success and len(calls) <= 2
    assert np.allclose(kept.q, res.q, rtol=0, atol=1e-9 * 0.3)


def test_kept_factor_reaches_the_same_states_with_fewer_tangents():
    """A shallow two-bar truss released from a perturbed state, undamped then damped: chord
    iterations on a kept factor give the states of full Newton to the step tolerance."""
    s = Structure([[-1.0, 0, 0], [0.0, 0, 0.1], [1.0, 0, 0]])
    s.add_bars([[0, 1], [1, 2]], EA=1e4)
    s.fix([0, 2])
    s.fix([1], "xy")
    s.add_point_mass([1], 1.0)
    s.add_load([1], [0, 0, -50.0])
    system = build_system(s)
    calls = []
    tangent_free = system.tangent_free
    system.tangent_free = lambda q: calls.append(1) or tangent_free(q)
    out = {}
    for keep in (False, True):
        calls.clear()
        res = implicit_euler(system, 2e-3, 0.6, damping=2.0, keep_factor=keep, rtol=1e-11, save_every=10)
        assert res.success, res.message
        out[keep] = (res, len(calls))
    (full, n_full), (kept, n_kept) = out[False], out[True]
    assert n_kept < 0.5 * n_full
    assert len(full.states) == len(kept.states) > 20
    for (t1, q1), (t2, q2) in zip(full.states, kept.states):
        assert t1 == t2 and abs(q1[5] - q2[5]) < 1e-8 * 0.1
