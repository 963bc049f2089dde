"""Critical points inside a step, located by a safeguarded secant on a test function.

A sign change of ``dp/ds`` over a step is a *limit point*; a change of the
count of negative eigenvalues while ``p`` keeps its direction is a
*bifurcation point*. Each is the root of a smooth test function of the arc
length ``sigma`` inside the step: ``dp/ds`` at a limit point, the eigenvalue
of the tangent closest to zero at a bifurcation point. The root is bracketed
by points on either side of the event, told apart exactly as the step told
them (the sign of ``dp/ds``, the count of negative eigenvalues), so the
test function only chooses where to look next: the secant of the bracket
(regula falsi with the Illinois weighting), a bisection when two trials have
not halved the bracket or the test function gives no useful value.

Location ends when the critical load is known to ``critical_rtol`` (relative):
at a bifurcation the bracket in the parameter is that narrow; at a limit point,
where the parameter is stationary, the parabola through the bracket,
``|dp/ds|`` falling linearly to zero, bounds the distance from the reported
point's parameter to the extremum by ``|dp/ds_lo - dp/ds_hi| w / 2`` (``w``
the bracket's arc length). Trial points are kept at least half the needed
bracket from its ends, so that a secant estimate close to the root closes the
bracket from the other side. Each trial point is corrected from the
interpolation of the points that bracket it and reported with the state, the
generalised load and the critical mode
(:class:`~shellform.solvers.continuation.results.PathEvent`).
"""

from __future__ import annotations

import math
import time

import numpy as np
import scipy.sparse.linalg as spla

from ..linear import SingularMatrixError, single_threaded
from ..stability import DENSE_LIMIT, InertiaError, critical_modes, eigsh_nearest_zero
from .corrector import correct
from .problem import BranchCrossing, LocationFailure, StepFailure, factor_alive
from .results import PathEvent

#: Most trial points of one location (a bisection to ``locate_tol = 1e-8`` takes 27).
MAX_TRIALS = 60


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
        raise BranchCrossing(
            f"the point at arc length {sigma:.3e} inside the step is not between its neighbours on the path "
            "(another branch crosses this step)"
        )
    return u, p, q, r


def eigenvalue_near_zero(K, F) -> float | None:
    """The eigenvalue of ``K`` closest to zero, from the factor ``F`` of ``K`` itself (None if that fails).

    A test function only: a few Lanczos iterations in shift-invert mode about
    zero with the solves of the factor the trial point has anyway; dense
    below :data:`~shellform.solvers.stability.DENSE_LIMIT` unknowns.
    """
    n = K.shape[0]
    try:
        if n <= DENSE_LIMIT:
            import scipy.linalg as sla

            with single_threaded():
                w = sla.eigvalsh(K.toarray())
            return float(w[np.argmin(np.abs(w))])
        w = eigsh_nearest_zero(K, F.solve, tol=1e-6)
        return float(w[0])
    except (SingularMatrixError, RuntimeError, ValueError, spla.ArpackNoConvergence):
        return None


def critical_mode(tr, K, F=None) -> tuple[float, np.ndarray]:
    """The eigenpair of ``K`` closest to zero at a located event (unit vector, largest entry positive).

    The reported point lies next to the critical point, not on it, so ``K`` is
    regular and its own factor inverts it: Lanczos about zero converges in a few
    iterations, the critical eigenvalue being far nearer zero than the next. A
    shift off zero relative to the largest diagonal entry (``critical_modes``)
    lies among the soft eigenvalues of a rod network, twelve orders of
    magnitude below that entry, and took thousands of iterations at each of the
    hemisphere's folds. ``F``: the factor of ``K`` the location made, used
    while it can still solve. Dense below ``DENSE_LIMIT`` unknowns, and
    ``critical_modes`` where the factorisation fails.
    """
    n = K.shape[0]
    if n > DENSE_LIMIT:
        if not factor_alive(F):
            F = tr.pb.factor(K)
        if F is not None:
            try:
                w, V = eigsh_nearest_zero(K, F.solve, vectors=True)
                v = V[:, 0]
                return float(w[0]), v * np.sign(v[np.argmax(np.abs(v))])
            except (SingularMatrixError, RuntimeError, ValueError, spla.ArpackNoConvergence):
                pass
    w, V = critical_modes(K, 1)
    return float(w[0]), V[:, 0]


class _Trial:
    """One point of the bracket: state, side of the event, test function and tangent."""

    __slots__ = ("sigma", "pt", "before", "f", "tangent", "K", "F")

    def __init__(self, sigma, pt, before, f, tangent=None, K=None, F=None):
        self.sigma, self.pt, self.before, self.f, self.tangent, self.K = sigma, pt, before, f, tangent, K
        self.F = F  # the factor of K, while no later factorisation has taken its storage


def _probe(tr, kind, pt, u0, p0, sign_A, n_A, sigma) -> _Trial:
    """Side of the event and test function at a path point."""
    u, p, q, r = pt
    K, g = tr.pb.jacobian(u, p, q)
    F = tr.pb.factor(K)
    try:
        t_du, t_dp = tr.tangent_from(K, g, F, u - u0, p - p0)
        tangent = (t_du, t_dp)
    except SingularMatrixError:
        if kind == "limit":
            raise
        tangent = None
    if kind == "limit":
        return _Trial(sigma, pt, math.copysign(1.0, t_dp) == sign_A, t_dp, tangent, K, F)
    before = tr.count(K, F, signed=True) == n_A
    f = eigenvalue_near_zero(K, F) if F is not None else None
    return _Trial(sigma, pt, before, f, tangent, K, F)


def _needed_width(kind, lo: _Trial, hi: _Trial, rtol: float) -> float:
    """Bracket width in arc length at which the critical load is known to ``rtol``."""
    w = hi.sigma - lo.sigma
    p_scale = max(abs(lo.pt[1]), abs(hi.pt[1]))
    if p_scale == 0.0 or rtol <= 0.0:
        return 0.0
    if kind == "limit":
        df = abs(lo.f - hi.f) if (lo.f is not None and hi.f is not None) else 0.0
        return 2.0 * rtol * p_scale / df if df > 0.0 else 0.0
    dp = abs(hi.pt[1] - lo.pt[1])
    return rtol * p_scale * w / dp if dp > 0.0 else math.inf


def _secant(a: tuple, b: tuple) -> float | None:
    """Root of the line through ``(sigma, f)`` pairs ``a`` and ``b`` (None when there is none)."""
    (sa, fa), (sb, fb) = a, b
    if fa is None or fb is None or fa == fb:
        return None
    s = sb - fb * (sb - sa) / (fb - fa)
    return s if np.isfinite(s) else None


def _next_sigma(lo: _Trial, hi: _Trial, f_lo, f_hi, history: list, bisect: bool, margin: float) -> float:
    """The next trial point inside the bracket ``[lo, hi]``, at least ``margin`` from its ends.

    The secant through the last two trials (superlinear, also when they lie on
    one side of the root); where it leaves the bracket, the secant of the
    bracket's ends with their Illinois weights ``f_lo``, ``f_hi``; the midpoint
    when ``bisect`` or neither is defined.
    """
    mid = 0.5 * (lo.sigma + hi.sigma)
    s = None
    if not bisect:
        s = _secant(history[-2], history[-1]) if len(history) >= 2 else None
        if s is None or not lo.sigma < s < hi.sigma:
            s = _secant((lo.sigma, f_lo), (hi.sigma, f_hi)) if (
                f_lo is not None and f_hi is not None and f_lo * f_hi < 0.0) else None
    if s is None or not lo.sigma < s < hi.sigma:
        return mid
    margin = min(margin, 0.25 * (hi.sigma - lo.sigma))
    return min(max(s, lo.sigma + margin), hi.sigma - margin)


def _end_trial(tr, kind, B, u0, p0, sign_A, n_A, ds_step) -> _Trial:
    """The step end B as the bracket end past the event, from the linearisation the tracer has just made."""
    end = (B.u, B.p, B.q, B.r)
    lin = tr.last_linearisation
    known = lin is not None and lin[0] is B.u
    K = lin[1] if known else None
    F = lin[3] if known else None
    if kind == "limit":
        return _Trial(ds_step, end, False, B.t_dp, (B.t_du, B.t_dp), K, F)
    if known and factor_alive(F):
        f = eigenvalue_near_zero(K, F)
    else:
        trial = _probe(tr, kind, end, u0, p0, sign_A, n_A, ds_step)
        K, f, F = trial.K, trial.f, trial.F
    return _Trial(ds_step, end, False, f, (B.t_du, B.t_dp), K, F)


def locate(tr, kind, A, B, ds_step, n_A, must_locate: bool = False):
    """Locate the event of ``kind`` between point A (sigma = 0) and the step end B (a StepPoint).

    Returns the :class:`PathEvent` at the bracket end past the event and that
    point's ``(u, p, q)``. Raises :class:`BranchCrossing` when a point inside
    the step is not on the path between A and B: B lies on another branch,
    and the step must be taken again, shorter. Any other failure to locate
    raises :class:`LocationFailure` when ``must_locate``, and otherwise gives
    an event marked not located, with the reason.
    """
    t0 = time.perf_counter()
    u0, p0, tA_du, tA_dp = A
    sign_A = math.copysign(1.0, tA_dp)
    located, last = False, None
    hi = _Trial(ds_step, (B.u, B.p, B.q, B.r), False, None, (B.t_du, B.t_dp))
    lo = _Trial(0.0, (u0, p0, tr.pb.state(u0, p0), None), True, tA_dp if kind == "limit" else None)
    try:
        hi = _end_trial(tr, kind, B, u0, p0, sign_A, n_A, ds_step)
        if kind != "limit":
            lo = _probe(tr, kind, lo.pt, u0, p0, sign_A, n_A, 0.0)
            lo.before = True
        lo, hi = _narrow(tr, kind, A, lo, hi, tr.o.locate_tol * ds_step, n_A)
        located = True
    except BranchCrossing:
        tr.timer.add("event_location", t0)
        raise
    except (StepFailure, SingularMatrixError) as exc:
        if must_locate:
            tr.timer.add("event_location", t0)
            raise LocationFailure(f"{kind} point not located: {exc}") from None
        last = str(exc)
    # report the bracket end past the event (the step end if location failed at once); at a limit
    # point the end with the smaller dp/ds, the nearer to the extremum of the parameter
    at = hi
    if located and kind == "limit" and lo.f is not None and hi.f is not None and lo.sigma > 0.0 \
            and abs(lo.f) < abs(hi.f):
        at = lo
    ev = _event(tr, kind, at, (lo, hi), A, n_A, "" if located else f"location stopped early: {last}")
    tr.timer.add("event_location", t0)
    return ev, at.pt[:3]


def _narrow(tr, kind, A, lo, hi, floor, n_A):
    """Close the bracket ``(lo, hi)`` on the event: safeguarded secant (Illinois) steps on the test function.

    Returns the final bracket; raises StepFailure when it does not close in
    ``MAX_TRIALS`` trial points.
    """
    u0, p0, _, tA_dp = A
    sign_A = math.copysign(1.0, tA_dp)
    f_lo, f_hi = lo.f, hi.f
    side, trials, bisect = 0, 0, False
    history = [(lo.sigma, lo.f), (hi.sigma, hi.f)]
    while True:
        need = _needed_width(kind, lo, hi, tr.o.critical_rtol)
        if hi.sigma - lo.sigma <= max(floor, need):
            return lo, hi
        if trials >= MAX_TRIALS:
            raise StepFailure(f"not located in {MAX_TRIALS} trial points")
        sigma = _next_sigma(lo, hi, f_lo, f_hi, history, bisect, 0.5 * max(floor, need))
        pt = solve_between(tr, A, lo.pt, hi.pt, lo.sigma, hi.sigma, sigma)
        trial = _probe(tr, kind, pt, u0, p0, sign_A, n_A, sigma)
        trials += 1
        # safeguard: a trial that did not halve the test function is followed by a bisection
        f_prev = history[-1][1]
        bisect = not bisect and (trial.f is None or f_prev is None or abs(trial.f) > 0.5 * abs(f_prev))
        history.append((sigma, trial.f))
        if trial.before:
            lo, f_lo = trial, trial.f
            if side == -1 and f_hi is not None:
                f_hi *= 0.5  # Illinois: the end kept twice counts half, so that the bracket closes
            side = -1
        else:
            hi, f_hi = trial, trial.f
            if side == 1 and f_lo is not None:
                f_lo *= 0.5
            side = 1


def _event(tr, kind, at, bracket, A, n_A, message: str) -> PathEvent:
    """The event reported at the trial point ``at`` of the final ``bracket``: its state, mode and tangent."""
    lo, hi = bracket
    _, _, tA_du, tA_dp = A
    u, p, q, r = at.pt
    if r is None:
        r = tr.system.residual(q, tr.pb.lam_mu(p)[0])
    K = at.K
    if K is None or at.tangent is None:
        K, g = tr.pb.jacobian(u, p, q)
        F = tr.pb.factor(K)
        try:
            t_du, t_dp = tr.tangent_from(K, g, F, tA_du, tA_dp)
        except SingularMatrixError:
            t_du, t_dp = tA_du, tA_dp
    else:
        t_du, t_dp = at.tangent
        if tr.dot(t_du, t_dp, tA_du, tA_dp) < 0.0:
            t_du, t_dp = -t_du, -t_dp
    t1 = time.perf_counter()
    try:
        eig, vec = critical_mode(tr, K, at.F if K is at.K else None)
    except InertiaError:
        eig, vec = float("nan"), np.zeros(tr.free.size)
    tr.timer.add("stability", t1)
    mode = np.zeros(tr.system.n_dof)
    mode[tr.free] = vec
    reactions = np.zeros(tr.system.n_dof)
    reactions[tr.system.constrained] = r[tr.system.constrained]
    return PathEvent(
        **tr.location(q, r, p, tr.s + at.sigma), kind=kind, step=tr.step + 1,
        n_negative_before=int(n_A), n_negative_after=-1, located=not message, bracket=abs(hi.pt[1] - lo.pt[1]),
        arc_bracket=hi.sigma - lo.sigma, eigenvalue=eig, mode=mode, q=q.copy(), reactions=reactions,
        tangent=np.concatenate([t_du, [t_dp]]), message=message, history=tr.history(),
    )
