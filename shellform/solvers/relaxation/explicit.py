"""The explicit schemes: the paper's RK4 and leapfrog with kinetic damping.

``"rk4"`` integrates the damped motion ``m a + c v = -r(q)`` by classical
Runge-Kutta with a fixed step below the stability limit (a Gershgorin bound
of the rope stiffnesses over the masses, :func:`~.bounds.stable_time_step`).
``"kinetic"`` is leapfrog without viscosity: whenever the kinetic energy
passes a peak, the velocities are zeroed and the state moved back to the
peak (Cundall/Barnes), one force evaluation per step.
"""

from __future__ import annotations

import numpy as np

from ...errors import ModelError
from .bounds import bound_step
from .monitor import NOT_MEASURED, Monitor, converged_message, limit_message, not_finite_message


def explicit_step_size(system, st, dt, scheme):
    if dt is not None:
        if not (dt > 0 and np.isfinite(dt)):
            raise ModelError(f"relaxation: time step must be positive and finite, got {dt}")
        return float(dt)
    return bound_step(system, st.q, st.m_node, scheme, st.damping if scheme == "rk4" else 0.0)


def _start(system, st, options, callback, t0, scheme):
    """What both explicit schemes start from: load factor, step budget, monitor, time step, a work
    state and the size beyond which a coordinate means the motion has diverged."""
    mon = Monitor(system, st, scheme, options.lam, callback, options.report_every, t0, options.max_wall_time)
    h = explicit_step_size(system, st, options.dt, scheme)
    return options.lam, options.iteration_limit, mon, h, st.q.copy(), 1e6 * st.L_ref


def run_rk4(system, st, options, callback, t0):
    """The paper's scheme: classical RK4 of the damped motion until every node is at rest."""
    lam, max_it, mon, h, q, L_big = _start(system, st, options, callback, t0, "rk4")
    free = system.free
    m, c = st.m, st.damping

    def acc(qf, vf):
        q[free] = qf
        r = system.residual(q, lam)[free]
        mon.n_res += 1
        return (-r - c * m * vf) / m, r

    qf = st.q[free].copy()
    vf = st.v0.copy()
    qf_prev, vf_prev = qf, vf
    t = 0.0
    seen = NOT_MEASURED
    for it in range(max_it + 1):
        a1, r = acc(qf, vf)
        vmax, amax, rnorm = seen = mon.measure(vf, r, a1)
        if not (np.isfinite(amax) and np.isfinite(vmax)) or np.max(np.abs(qf)) > L_big:
            return mon.finish(qf_prev, vf_prev, False, not_finite_message(it, h), it, t, h, NOT_MEASURED)
        if mon.converged(vmax, amax):
            return mon.finish(qf, vf, True, converged_message(mon, it, vmax, amax), it, t, h, seen)
        if it == max_it:
            break
        stop = mon.tick(it, t, vmax, amax, rnorm, qf, vf)
        if stop:
            return mon.finish(qf, vf, False, stop, it, t, h, seen)
        qf_prev, vf_prev = qf, vf
        v2 = vf + 0.5 * h * a1
        a2, _ = acc(qf + 0.5 * h * vf, v2)
        v3 = vf + 0.5 * h * a2
        a3, _ = acc(qf + 0.5 * h * v2, v3)
        v4 = vf + h * a3
        a4, _ = acc(qf + h * v3, v4)
        qf = qf + (h / 6.0) * (vf + 2.0 * v2 + 2.0 * v3 + v4)
        vf = vf + (h / 6.0) * (a1 + 2.0 * a2 + 2.0 * a3 + a4)
        t += h
    return mon.finish(qf, vf, False, limit_message(mon, max_it, seen.vmax, seen.amax), max_it, t, h, seen)


def run_kinetic(system, st, options, callback, t0):
    """Leapfrog with kinetic damping until every node is at rest."""
    lam, max_it, mon, h, q, L_big = _start(system, st, options, callback, t0, "kinetic")
    free = system.free
    m = st.m

    def force(qf):
        q[free] = qf
        mon.n_res += 1
        return system.residual(q, lam)[free]

    qf = st.q[free].copy()
    v = st.v0.copy()  # velocity at the half step t - h/2
    qf_prev = qf
    r = force(qf)
    ke_prev = 0.5 * float(np.dot(m * v, v))
    t = 0.0
    seen = NOT_MEASURED
    for it in range(max_it + 1):
        a = -r / m
        vmax, amax, rnorm = seen = mon.measure(v, r, a)
        if not (np.isfinite(amax) and np.isfinite(vmax)) or np.max(np.abs(qf)) > L_big:
            return mon.finish(qf_prev, np.zeros_like(qf), False, not_finite_message(it, h), it, t, h, NOT_MEASURED)
        if mon.converged(vmax, amax):
            return mon.finish(qf, v, True, converged_message(mon, it, vmax, amax), it, t, h, seen)
        if it == max_it:
            break
        stop = mon.tick(it, t, vmax, amax, rnorm, qf, v)
        if stop:
            return mon.finish(qf, v, False, stop, it, t, h, seen)
        qf_prev = qf
        v_new = v + h * a
        q_new = qf + h * v_new
        ke = 0.5 * float(np.dot(m * v_new, v_new))
        if ke < ke_prev:
            # the kinetic energy peaked during the last steps: go back to the peak
            # (quadratic interpolation of the trajectory, Barnes' correction) and
            # restart from rest there
            qf = q_new - 1.5 * h * v_new + 0.5 * h * h * a
            v = np.zeros_like(qf)
            ke_prev = 0.0
        else:
            qf, v = q_new, v_new
            ke_prev = ke
        r = force(qf)
        t += h
    return mon.finish(qf, v, False, limit_message(mon, max_it, seen.vmax, seen.amax), max_it, t, h, seen)
