"""Critical points inside a step, located by bisection on the arc length.

A sign change of ``dp/ds`` over a step is a *limit point*; a change of the
count of negative eigenvalues while ``p`` keeps its direction is a
*bifurcation point*. Both are located by bisection on the arc length within the
step, each trial point corrected from the interpolation of the points that
bracket it, and reported with the state, the generalised load and the critical
mode (:class:`~shellform.solvers.continuation.results.PathEvent`).
"""

from __future__ import annotations

import math
import time

import numpy as np

from ..linear import SingularMatrixError
from ..stability import InertiaError, critical_modes
from .corrector import correct
from .problem import StepFailure
from .results import PathEvent


def solve_between(tr, A, lo_pt, hi_pt, lo, hi, sigma):
    """Path point at arc length ``sigma`` from A, between two known path points.

    The predictor interpolates the bracketing points, so the corrector
    stays on this path segment even where another branch crosses nearby;
    a solution that is not between its neighbours is rejected.
    """
    u0, p0 = A[0], A[1]
    w = (sigma - lo) / (hi - lo)
    du = (1 - w) * (lo_pt[0] - u0) + w * (hi_pt[0] - u0)
    dp = (1 - w) * (lo_pt[1] - p0) + w * (hi_pt[1] - p0)
    u, p, q, r, _ = correct(tr, u0, p0, du, dp, sigma)
    d_lo = tr.norm(u - lo_pt[0], p - lo_pt[1])
    d_hi = tr.norm(u - hi_pt[0], p - hi_pt[1])
    if d_lo > 2.0 * (sigma - lo) + 1e-12 * sigma or d_hi > 2.0 * (hi - sigma) + 1e-12 * sigma:
        raise StepFailure(
            f"bisection point at arc length {sigma:.3e} is not between its neighbours on the path "
            "(another branch crosses this step)"
        )
    return u, p, q, r

def locate(tr, kind, A, B, ds_step, n_A):
    """Bisection on the arc length between point A (sigma = 0) and the step end B."""
    t0 = time.perf_counter()
    u0, p0, tA_du, tA_dp = A
    sign_A = math.copysign(1.0, tA_dp)
    lo, hi = 0.0, ds_step
    lo_pt, hi_pt = (u0, p0, tr.pb.state(u0, p0), None), B
    located, last = False, None
    tol = tr.o.locate_tol * ds_step
    try:
        while hi - lo > tol:
            mid = 0.5 * (lo + hi)
            pt = solve_between(tr, A, lo_pt, hi_pt, lo, hi, mid)
            u, p, q, r = pt
            K, g = tr.pb.jacobian(u, p, q)
            if kind == "limit":
                F = tr.pb.factor(K)
                du, dp = tr.tangent_from(K, g, F, u - u0, p - p0)
                before = math.copysign(1.0, dp) == sign_A
            else:
                before = tr.count(K, None, signed=True) == n_A
            if before:
                lo, lo_pt = mid, pt
            else:
                hi, hi_pt = mid, pt
        located = True
    except (StepFailure, SingularMatrixError) as exc:
        last = str(exc)
    # report the bracket end past the event (the step end if bisection failed at once)
    sigma = hi
    u, p, q, r = hi_pt
    if r is None:
        r = tr.system.residual(q, tr.pb.lam_mu(p)[0])
    p_lo, p_hi = lo_pt[1], hi_pt[1]
    K, g = tr.pb.jacobian(u, p, q)
    F = tr.pb.factor(K)
    try:
        t_du, t_dp = tr.tangent_from(K, g, F, tA_du, tA_dp)
    except SingularMatrixError:
        t_du, t_dp = tA_du, tA_dp
    t1 = time.perf_counter()
    try:
        w, V = critical_modes(K, 1)
        eig, vec = float(w[0]), V[:, 0]
    except InertiaError:
        eig, vec = float("nan"), np.zeros(tr.free.size)
    tr.timer.add("stability", t1)
    mode = np.zeros(tr.system.n_dof)
    mode[tr.free] = vec
    reactions = np.zeros(tr.system.n_dof)
    reactions[tr.system.constrained] = r[tr.system.constrained]
    bracket = abs(p_hi - p_lo)
    ev = PathEvent(
        **tr.location(q, r, p, tr.s + sigma), kind=kind, step=tr.step + 1,
        n_negative_before=int(n_A), n_negative_after=-1, located=located, bracket=bracket,
        arc_bracket=hi - lo, eigenvalue=eig, mode=mode, q=q.copy(), reactions=reactions,
        tangent=np.concatenate([t_du, [t_dp]]),
        message="" if located else f"bisection stopped early: {last}",
    )
    tr.timer.add("event_location", t0)
    return ev, (u, p, q)
