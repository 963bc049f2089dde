"""The corrector: Newton on the equilibrium equations plus the arc-length constraint (Crisfield).

At the current increment ``(du, dp)`` with residual ``R``, solve ``K a = -R`` and
``K b = -g``; the new increment is ``(w + delta b, dp + delta)`` with
``w = du + a`` and ``delta`` the root of the constraint closest to the current
increment. Next to a critical point, or where ``K`` cannot be factorised, a
bordered Newton step with the linearised constraint is taken instead. The
functions take the tracer (:class:`~shellform.solvers.continuation.tracer.Tracer`)
whose metric, problem and counters they use.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from ..equilibrium import EquilibriumCheck, forces_in_play
from ..linear import SingularMatrixError
from .problem import StepFailure, factor_alive

#: Where nothing is counted at a converged point (``stability`` off), its path tangent comes from the
#: corrector's last tangent and factor when these were taken within this share of the step from
#: the point (the last correction is 1e-5 to 1e-3 of the step on the lattice domes and the
#: hemispheres): one factorisation less per step (``benchmarks/bench_point_linearisation.py``).
#: Not where the point's inertia is counted, which must be that of the point itself (an
#: eigenvalue within the last correction of zero could change sign), nor at the trial points
#: of an event's location, whose test function must be exact for a tight tolerance on the load.
REUSE_DISTANCE = 1e-3


class LastLinearisation(NamedTuple):
    """The corrector's last tangent ``K``, ``g = dG/dp`` and factor ``F``, taken ``distance`` (in the
    arc-length metric) from the point ``(u, p)`` it converged to."""

    u: np.ndarray
    p: float
    K: object
    g: np.ndarray
    F: object
    distance: float


@dataclass
class StepPoint:
    """A converged point at the end of a step, with its linearisation.

    Attributes
    ----------
    u, p : ndarray, float
        Free DOFs and parameter.
    q, r : ndarray
        Full state and residual.
    iterations : int
        Corrector iterations.
    du, dp : ndarray, float
        The step's increment.
    t_du, t_dp : ndarray, float
        Unit path tangent at the point, in the direction of travel.
    n_neg : int
        Negative eigenvalues of the tangent (-1 when not counted).
    """

    u: np.ndarray
    p: float
    q: np.ndarray
    r: np.ndarray
    iterations: int
    du: np.ndarray
    dp: float
    t_du: np.ndarray
    t_dp: float
    n_neg: int


def correct(tr, u0, p0, du, dp, ds):
    """Newton on ``G = 0`` plus the arc-length constraint from the predictor ``(du, dp)``."""
    o = tr.o
    max_iter = o.max_iterations
    tr.pb.new_point()
    tr.corrector_last = None
    complex_roots = 0
    norm0 = previous = None
    last = None  # the last iteration's linearisation and the increment it was taken at
    for it in range(max_iter + 1):
        u, p = u0 + du, p0 + dp
        R, r, q = tr.pb.residual(u, p)
        nR = float(np.linalg.norm(R))
        if not np.isfinite(nR):
            raise StepFailure(f"non-finite residual at corrector iteration {it}")
        eq = equilibrium(tr, nR, r, p, nR if norm0 is None else norm0)
        # stalled near the rounding level: no iteration can do better
        stalled = eq.near_roundoff and (it == max_iter or (previous is not None and nR > 0.1 * previous))
        if stalled and not (eq.converged or eq.acceptable_at_roundoff):
            raise StepFailure(eq.roundoff_failure())
        if eq.converged or stalled:
            if last is not None:
                K, g, F, du_k, dp_k = last
                tr.corrector_last = LastLinearisation(u, p, K, g, F, tr.norm(du - du_k, dp - dp_k))
            return u, p, q, r, it
        previous = nR
        if norm0 is None:
            norm0 = max(nR, 1e-300)
        elif nR > 1e8 * norm0:
            raise StepFailure(f"corrector diverged (|G| grew from {norm0:.3e} to {nR:.3e})")
        if it == max_iter:
            break
        tr.newton_total += 1
        K, g = tr.pb.jacobian(u, p, q)
        F = tr.pb.factor(K)
        last = (K, g, F, du, dp)
        a = b = None
        if F is not None:
            try:
                a = tr.pb.solve(F, -R)
                b = tr.pb.solve(F, -g)
            except SingularMatrixError:
                a = b = None
        if a is not None and float(np.linalg.norm(b)) * tr.kbar > 1e6 * max(float(np.linalg.norm(g)), 1e-300):
            # nearly singular tangent (at a critical point): the two solves are huge and
            # their combination cancels, so use the bordered system instead
            a = b = None
        if a is not None:
            du, dp, real = constrained_update(tr, du, dp, a, b, ds)
            complex_roots += not real
            if complex_roots > 3:
                raise StepFailure("arc-length constraint has no real root (step too long for the curvature)")
        else:
            # singular tangent: bordered Newton step with the linearised constraint
            cval = tr.dot(du, dp, du, dp) - ds * ds
            try:
                x, y = tr.pb.bordered_solve(K, g, 2.0 * du, 2.0 * tr.c2 * dp, -R, -cval, F)
            except SingularMatrixError as exc:
                raise StepFailure(f"singular bordered system: {exc}", singular=True) from None
            du, dp = du + x, dp + y
        if not (np.all(np.isfinite(du)) and np.isfinite(dp)):
            raise StepFailure(f"non-finite correction at iteration {it + 1}")
    raise StepFailure(f"corrector did not converge in {max_iter} iterations ({eq.describe()})")


def constrained_update(tr, du, dp, a, b, ds):
    """The new increment ``(w + delta b, dp + delta)``, ``w = du + a``, on the arc-length sphere of radius ``ds``.

    Of the two roots ``delta``, the one whose increment turns least from ``(du, dp)``; with no real
    root, the point of the line nearest the sphere. Returns ``(du, dp, real)``.
    """
    w = du + a
    A = float(b @ b) + tr.c2
    B = 2.0 * (float(w @ b) + tr.c2 * dp)
    C = float(w @ w) + tr.c2 * dp * dp - ds * ds
    disc = B * B - 4.0 * A * C
    if not (disc >= 0.0 and A > 0.0):
        rt = -B / (2.0 * A) if A > 0 else 0.0
        return w + rt * b, dp + rt, False
    sq = math.sqrt(disc)
    # numerically stable pair of roots
    qq = -0.5 * (B + math.copysign(sq, B))
    roots = [qq / A, C / qq] if qq != 0.0 else [0.0, 0.0]
    best = None
    for rt in roots:
        du_n, dp_n = w + rt * b, dp + rt
        score = tr.dot(du_n, dp_n, du, dp)
        if best is None or score > best[0]:
            best = (score, du_n, dp_n)
    return best[1], best[2], True


def point_linearisation(tr, u, p, q, length: float):
    """``(K, g, F)`` at the converged point ``(u, p)`` reached by a step of ``length``.

    The corrector's last tangent and factor when they were taken within
    ``REUSE_DISTANCE`` of that step from the point (at the iterate before the
    last correction), else a new tangent and factorisation there.
    """
    last = tr.corrector_last
    if (last is not None and last.u is u and last.p == p and last.distance <= REUSE_DISTANCE * length
            and (last.F is None or factor_alive(last.F))):
        return last.K, last.g, last.F
    K, g = tr.pb.jacobian(u, p, q)
    return K, g, tr.pb.factor(K)


def equilibrium(tr, norm: float, r: np.ndarray, p: float, unloaded_scale: float) -> EquilibriumCheck:
    """The equilibrium test of a corrector iterate (residual norm ``norm``, full residual ``r``).

    The forces in play are those of the last accepted point, the applied
    loads and the reactions at this iterate; where all are zero (nothing
    loaded yet, displacement control at ``mu = 0``) the residual is judged
    against ``unloaded_scale``, the predictor's imbalance.
    """
    o = tr.o
    if tr.play is None:
        tr.play = forces_in_play(tr.system, tr.q, tr.pb.lam_mu(tr.p)[0])
    ext = tr.pb.f_dead + tr.pb.lam_mu(p)[0] * tr.pb.f_ref
    reactions = r[tr.system.constrained]
    applied = float(np.linalg.norm(ext))
    scale = max(applied, float(np.linalg.norm(reactions)), tr.play[0])
    scale_max = max(float(np.max(np.abs(ext), initial=0.0)), float(np.max(np.abs(reactions), initial=0.0)),
                    tr.play[1])
    if scale == 0.0:
        scale = scale_max = unloaded_scale
    return EquilibriumCheck(norm, scale, o.rtol * scale + o.atol, tr.round_floor, o.roundoff_rtol,
                            applied, float(np.max(np.abs(r[tr.free]), initial=0.0)), scale_max)


def land(tr, u, p, lo_b, hi_b) -> StepPoint | None:
    """The point of the last step exactly at the parameter bound it crossed (None if Newton fails)."""
    pb = hi_b if p > hi_b else lo_b
    w = (pb - tr.p) / (p - tr.p) if p != tr.p else 1.0
    if not 0.0 <= w <= 1.0:
        return None
    u = tr.u + w * (u - tr.u)
    tr.pb.new_point()
    previous = None
    for it in range(tr.o.max_iterations + 1):
        R, r, q = tr.pb.residual(u, pb)
        nR = float(np.linalg.norm(R))
        if not np.isfinite(nR):
            return None
        eq = equilibrium(tr, nR, r, pb, nR if previous is None else previous)
        stalled = eq.near_roundoff and previous is not None and nR > 0.1 * previous
        if stalled and not eq.acceptable_at_roundoff:
            return None
        previous = nR
        if eq.converged or stalled:
            du, dp = u - tr.u, pb - tr.p
            try:
                t_du, t_dp, n_neg, _ = tr.analyse_point(u, pb, du, dp, q)
            except SingularMatrixError:
                return None
            return StepPoint(u, pb, q, r, it, du, dp, t_du, t_dp, n_neg)
        K, _ = tr.pb.jacobian(u, pb, q)
        F = tr.pb.factor(K)
        if F is None:
            return None
        try:
            u = u + tr.pb.solve(F, -R)
        except SingularMatrixError:
            return None
        tr.newton_total += 1
    return None
