"""The bookkeeping every scheme shares: tolerances, history, the progress callback, the result."""

from __future__ import annotations

import time
from typing import NamedTuple

import numpy as np

from .bounds import nodal_max
from .result import RelaxationProgress, RelaxationResult


class Measures(NamedTuple):
    """How far a state is from rest: the largest nodal speed and acceleration, and the residual norm."""

    vmax: float
    amax: float
    rnorm: float


#: the measures of a state that could not be measured (it is no longer finite)
NOT_MEASURED = Measures(np.nan, np.nan, np.nan)


class Monitor:
    """Shared bookkeeping: tolerances, history, callback, finishing."""

    def __init__(self, system, st, scheme, lam, callback, every, t0, max_wall_time):
        self.system, self.st, self.scheme, self.lam = system, st, scheme, lam
        self.callback, self.every, self.t0, self.max_wall_time = callback, every, t0, max_wall_time
        self.history = {"iteration": [], "max_velocity": [], "max_acceleration": [], "residual_norm": []}
        self.n_res = 0
        self.n_fact = 0
        self.n_cg = 0
        self.n_local = 0
        self.n_corrected = 0
        self.n_repaired = 0
        self.rejected = 0

    def measure(self, v_free, r_free, a_free=None) -> Measures:
        """Nodal maxima; the acceleration is ``-r / m`` unless given."""
        vmax = nodal_max(self.system, v_free)
        amax = nodal_max(self.system, (-r_free / self.st.m) if a_free is None else a_free)
        return Measures(vmax, amax, float(np.linalg.norm(r_free)))

    def converged(self, vmax, amax) -> bool:
        return vmax <= self.st.v_tol and amax <= self.st.a_tol

    def full(self, x_free, base=None):
        """A vector over all DOFs: ``x_free`` at the free ones, ``base`` (or zero) elsewhere."""
        out = np.zeros(self.system.n_dof) if base is None else base.copy()
        out[self.system.free] = x_free
        return out

    def tick(self, it, t, vmax, amax, rnorm, q_free, v_free) -> str | None:
        """Record, call back with the current state; return a reason to stop, if any."""
        if it % self.every == 0:
            for k, val in zip(self.history, (it, vmax, amax, rnorm)):
                self.history[k].append(val)
            if self.callback is not None:
                info = RelaxationProgress(self.scheme, it, t, vmax, amax, rnorm, time.perf_counter() - self.t0,
                                          q=self.full(q_free, self.st.q), v=self.full(v_free))
                if self.callback(info):
                    return f"stopped by the progress callback after {it} iterations"
        if self.max_wall_time is not None and time.perf_counter() - self.t0 > self.max_wall_time:
            return f"not converged within the wall-time limit of {self.max_wall_time:g} s ({it} iterations)"
        return None

    def finish(self, q_free, v_free, success, message, it, t, h, measures: Measures) -> RelaxationResult:
        """The result of a run that ends at ``(q_free, v_free)`` after ``it`` iterations, at time ``t``."""
        q = self.full(q_free, self.st.q)  # constrained DOFs at their prescribed values
        v = self.full(v_free)
        return RelaxationResult(
            q=q, v=v, success=success, message=message, scheme=self.scheme, iterations=it,
            max_velocity=measures.vmax, max_acceleration=measures.amax, residual_norm=measures.rnorm,
            velocity_tol=self.st.v_tol, acceleration_tol=self.st.a_tol, time=t, time_step=h,
            wall_time_s=time.perf_counter() - self.t0, reactions=self.system.reactions(q, self.lam),
            residual_evaluations=self.n_res, factorizations=self.n_fact, rejected_steps=self.rejected,
            linear_iterations=self.n_cg, local_steps=self.n_local, corrected_solves=self.n_corrected,
            repaired_steps=self.n_repaired,
            history=self.history, start=self.st.start,
        )


def converged_message(mon, it, vmax, amax):
    msg = (f"at rest after {it} iterations: max nodal velocity {vmax:.3e} <= {mon.st.v_tol:.3e} m/s, "
           f"max nodal acceleration {amax:.3e} <= {mon.st.a_tol:.3e} m/s^2")
    if mon.st.a_tol > mon.st.a_tol_asked:
        msg += (f" (acceleration tolerance raised from {mon.st.a_tol_asked:.3e} to the round-off level of "
                "the rope forces)")
    return msg


def not_finite_message(it, h):
    return (f"diverged at iteration {it}: the state is no longer finite (time step {h:.3e} s); "
            "reduce the time step")


def limit_message(mon, it, vmax, amax):
    return (f"not converged in {it} iterations: max nodal velocity {vmax:.3e} (tolerance {mon.st.v_tol:.3e}), "
            f"max nodal acceleration {amax:.3e} (tolerance {mon.st.a_tol:.3e})")

