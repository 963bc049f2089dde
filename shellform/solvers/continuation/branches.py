"""Branch switching: leaving a bifurcation point along its critical mode.

The first step leaves the bifurcation along the critical mode (or a given
imperfection shape) made orthogonal to the primary path tangent; the
arc-length corrector then converges onto the secondary branch. A step that
falls back onto the primary branch is retried shorter and finally reported as
a failure.
"""

from __future__ import annotations

import numpy as np

from ..linear import SingularMatrixError
from .corrector import correct
from .problem import StepFailure


def leave_bifurcation(tr, u_b, p_b, t_du, t_dp, mode_free, side, ds):
    """Leave a bifurcation point along ``mode_free`` (orthogonalised against the path tangent)."""
    v_du = np.array(mode_free, dtype=float)
    v_dp = 0.0
    proj = tr.dot(v_du, v_dp, t_du, t_dp)
    v_du, v_dp = v_du - proj * t_du, v_dp - proj * t_dp
    nv = tr.norm(v_du, v_dp)
    if nv == 0.0 or not np.isfinite(nv):
        raise StepFailure("the branch-switching direction is parallel to the primary path")
    v_du, v_dp = side * v_du / nv, side * v_dp / nv
    last = ""
    for _ in range(6):
        try:
            u, p, q, r, its = correct(tr, u_b, p_b, ds * v_du, ds * v_dp, ds)
            du, dp = u - u_b, p - p_b
            along_primary = abs(tr.dot(du, dp, t_du, t_dp)) / max(tr.norm(du, dp), 1e-300)
            if along_primary < 0.95:
                return u, p, q, r, its, du, dp
            last = f"corrector returned to the primary branch (cosine {along_primary:.3f} with its tangent)"
        except (StepFailure, SingularMatrixError) as exc:
            last = str(exc)
        ds *= 0.5
    raise StepFailure(f"branch switching failed: {last}")


def switch_at(tr, u_b, p_b, t_du, t_dp, mode_free, s_b):
    """Make the first point of the secondary branch the tracer's current point (arc length ``s_b`` at the bifurcation)."""
    side = 1.0 if tr.o.branch_side >= 0 else -1.0
    ds = tr.o.switch_ds if tr.o.switch_ds is not None else tr.ds
    u, p, q, r, its, du, dp = leave_bifurcation(tr, u_b, p_b, t_du, t_dp, mode_free, side, ds)
    t_du2, t_dp2, n_neg, _ = tr.analyse_point(u, p, du, dp, q)
    tr.switches += 1
    tr.branch += 1
    tr.step += 1
    tr.s = s_b + tr.norm(du, dp)
    # the secondary branch starts with the step length that left the bifurcation
    tr.ds = min(max(tr.ds, tr.norm(du, dp)), tr.ds_max)
    tr.u, tr.p, tr.q = u, p, q
    tr.t_du, tr.t_dp, tr.n_neg = t_du2, t_dp2, n_neg
    tr.accept(q)
    tr.last_point = (q, r, p, its, tr.norm(du, dp), n_neg)
