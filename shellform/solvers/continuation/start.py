"""The start of a path: equilibrium at the first parameter, the arc-length metric and the first step.

The first point is a Newton solve at ``p0``. Its tangent sets the metric's
parameter weight ``c`` (``|du|^2 + c^2 dp^2 = ds^2``) from a typical stiffness,
so that a start next to a critical point does not distort it, and the first
arc length from the requested step, from the parameter bounds or from the
linearised distance to the nearest critical point
(:mod:`shellform.solvers.step_bounds`), which also caps the later steps.
"""

from __future__ import annotations

import math
import time

import numpy as np

from ...errors import MechanismError, ModelError
from ..equilibrium import roundoff_level
from ..linear import CholeskyFactor, LDLFactor, SingularMatrixError
from ..mechanism import describe_soft_modes
from ..newton import solve_static
from ..step_bounds import linearised_critical_increment
from .options import ContinuationOptions
from .results import PathPoint


def start(tr, q0, p0: float, direction: int) -> PathPoint:
    """Converge onto the path at ``p0``, set the tracer's metric and step bounds; the first point."""
    o = tr.o
    lam, mu = tr.pb.lam_mu(p0)
    st = solve_static(tr.system, q0, lam=lam, mu=mu, rtol=o.rtol, roundoff_rtol=o.roundoff_rtol, max_iter=50)
    q = st.q
    u = q[tr.free].copy()
    K, g = tr.pb.jacobian(u, p0, q)
    diag = np.abs(K.diagonal())
    # residuals cannot be computed more accurately than the rounding of the
    # member forces: stiffness times the rounding of the coordinates
    tr.round_floor = roundoff_level(diag, q)
    if not st.success:
        raise ModelError(f"no equilibrium at the starting parameter {p0}: {st.message}")
    # stiffness scale for the arc-length metric: the larger of the reference and
    # the starting state, so that a start next to a critical point does not distort it
    d_ref = np.abs(tr.pb.jacobian(tr.system.q_ref[tr.free], p0)[0].diagonal())
    kbar = [float(np.mean(d[d > 0])) for d in (diag, d_ref) if np.any(d > 0)]
    tr.kbar = max(kbar) if kbar else 1.0
    F = tr.pb.factor(K)
    b = _du_dp(tr, K, g, F)
    nb = float(np.linalg.norm(b))
    c = _parameter_weight(o, g, nb, tr.kbar)
    tr.c2 = c * c
    # no step may be longer than the linearised distance to the nearest critical point
    crit = critical_increment(tr, u, p0, K, F, b, direction, q)
    ds_crit = crit * math.sqrt(nb * nb + tr.c2) if crit is not None else math.inf
    ds = _first_arc_length(o, p0, direction, crit, math.sqrt(nb * nb + tr.c2))
    tr.ds = ds
    tr.ds_min = o.ds_min if o.ds_min is not None else ds * 1e-6
    # an explicit first step is the user's to take; after it no default step exceeds the estimate
    tr.ds_max = o.ds_max if o.ds_max is not None else min(ds * 10.0, max(ds, ds_crit))
    t_du, t_dp = tr.tangent_from(K, g, F, None, None)
    if direction < 0:
        t_du, t_dp = -t_du, -t_dp
    tr.u, tr.p, tr.q = u, float(p0), q
    tr.t_du, tr.t_dp = t_du, t_dp
    # the residual the point was converged with: accepting a state moves the rods' reference
    # frames, and where a rod's twist is held their new parametrisation balances it to a
    # different round-off (path-dependent, second order in the rotation since the last accepted state)
    r = tr.system.residual(q, lam)
    tr.accept(q)
    tr.n_neg = tr.count(K, F)
    tr.step, tr.branch, tr.s = 0, 0, 0.0
    return tr.record(q, r, p0, st.iterations, 0.0, tr.n_neg)


def _du_dp(tr, K, g, F) -> np.ndarray:
    """``du/dp = -K^-1 g`` at the start; a singular tangent is named by the motions it cannot resist."""
    b = None
    if F is not None:
        try:
            b = tr.pb.solve(F, -g)
        except SingularMatrixError:
            b = None
    if b is None:
        soft = describe_soft_modes(tr.system, K)
        raise MechanismError(
            f"the tangent is singular at the starting point: {soft}" if soft else
            "the tangent is singular at the starting point; start from a regular state "
            "(or use switch_branch from a located event)"
        )
    return b


def _parameter_weight(o: ContinuationOptions, g, nb: float, kbar: float) -> float:
    """``c`` of the metric ``|du|^2 + c^2 dp^2`` (zero for the cylindrical constraint)."""
    if o.constraint == "cylindrical":
        if nb == 0.0:
            raise ModelError("cylindrical arc length: the parameter does not move any free DOF")
        return 0.0
    if o.parameter_scale is not None:
        return float(o.parameter_scale)
    # du/dp of a typical stiffness rather than |K^-1 g|: defined and moderate
    # even when the start is close to a critical point
    ng = float(np.linalg.norm(g))
    return o.psi * (ng / kbar if ng > 0 else 1.0)


def _first_arc_length(o: ContinuationOptions, p0: float, direction: int, crit: float | None,
                      ds_per_dp: float) -> float:
    """The first step's arc length: ``ds``, or set by the first parameter increment."""
    if o.ds is not None:
        ds = float(o.ds)
    else:
        dp0 = o.initial_increment
        if dp0 is None:
            lo, hi = o.parameter_bounds
            span = hi - p0 if direction >= 0 else p0 - lo
            if span <= 0 or not (np.isfinite(span) or crit is not None):
                raise ModelError(
                    "continuation needs a step size: give ds, initial_increment or a finite parameter bound"
                )
            dp0 = min(span / 20.0, crit / 4.0 if crit is not None else math.inf)
        ds = abs(float(dp0)) * ds_per_dp
    if not (np.isfinite(ds) and ds > 0):
        raise ModelError(f"initial arc length must be positive and finite, got {ds}")
    return ds


def critical_increment(tr, u, p, K, F, du_dp, direction, q):
    """Linearised parameter increment to the nearest critical point ahead (None: none or unknown).

    Only from a start whose tangent is positive definite: factorised by
    Cholesky, or ``K = L D L^T`` with a positive ``D`` (see
    :func:`~shellform.solvers.step_bounds.linearised_critical_increment`).
    An estimate, not a stability check: a start it cannot judge goes
    without one, and so does a run on a branch its caller knows stable
    (``definite_branch`` without ``stability``: the caller counts and stops
    for itself).
    """
    if tr.o.definite_branch and not tr.o.stability:
        return None
    if isinstance(F, LDLFactor):
        try:
            if not np.all(F.d > 0.0):
                return None
        except SingularMatrixError:
            return None
    elif not isinstance(F, CholeskyFactor):
        return None
    t0 = time.perf_counter()
    crit = linearised_critical_increment(lambda uu, pp: tr.pb.jacobian(uu, pp), u, p, K, F, du_dp,
                                         1.0 if direction >= 0 else -1.0, float(np.max(np.abs(q))))
    tr.timer.add("step_bounds", t0)
    return crit
