"""Static equilibrium by Newton's method with a backtracking line search.

Stiff members
-------------
A straight Newton step that rotates an axially stiff member (an edge of a
nearly inextensible rod) also lengthens it, to second order, and the stiff
member turns that into a large spurious energy: the line search cuts the
step to a small fraction, the spurious axial forces stiffen the next tangent
like a taut string, and Newton crawls. When the full step is rejected, the
line search therefore also tries the trial states projected back onto the
linearised member lengths and joint gaps (:class:`StretchProjection`), which
rotate members instead of stretching them, and keeps the better of the two
at each step length: the iteration count no longer grows with the axial
stiffness. Measured (``python benchmarks/bench_rods.py --part
newton``) on a 40-edge cantilever under self-weight in 3 load steps: at
``EA L^2 / EI = 10^7`` 35 Newton iterations instead of 652 (and 24 halved
load steps), at ``10^9`` 35 instead of 7818.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from .equilibrium import ROUNDOFF_RTOL, check, forces_in_play
from .linear import LDLFactor, SingularMatrixError, factorize
from .mechanism import describe_soft_modes
from .options import with_overrides


@dataclass
class StaticResult:
    """Outcome of a static solve.

    Attributes
    ----------
    q : ndarray
        Final DOF vector (the last finite iterate when the solve failed).
    success : bool
        Whether the residual met the tolerance.
    message : str
        What happened, in words.
    iterations : int
        Newton iterations performed.
    residual_norms : list of float
        Norm of the free residual at each iterate (the first is the start).
    tolerance : float
        Residual norm that counts as converged.
    lam, mu : float
        Load factor and prescribed-displacement parameter of the solve.
    reactions : ndarray
        Support reactions at every DOF (zero where free).
    regularised_steps : int
        Steps where the tangent was singular or not a descent direction and a
        diagonal shift was added.
    wall_time_s : float
    forces_in_play : float
        The scale the residual was judged against (:mod:`shellform.solvers.equilibrium`).
    """

    q: np.ndarray
    success: bool
    message: str
    iterations: int
    residual_norms: list[float] = field(default_factory=list)
    tolerance: float = 0.0
    lam: float = 1.0
    mu: float = 0.0
    reactions: np.ndarray | None = None
    regularised_steps: int = 0
    wall_time_s: float = 0.0
    forces_in_play: float = float("nan")

    @property
    def residual_norm(self) -> float:
        return self.residual_norms[-1] if self.residual_norms else float("nan")


def _shift_sequence(K, rhs_norm, size, n_shifts=14):
    """Diagonal shifts to try after the plain Newton step: the first one limits
    the step to about a tenth of the model size (a trust region in disguise),
    then they grow by factors of 10."""
    diag = np.abs(K.diagonal())
    base = float(np.mean(diag[diag > 0])) if np.any(diag > 0) else 0.0
    first = max(1e-8 * base, rhs_norm / (0.1 * size), 1e-300)
    return [0.0] + [first * 10.0**k for k in range(n_shifts)]


@dataclass(frozen=True)
class NewtonOptions:
    """Options of :func:`solve_static`.

    Attributes
    ----------
    rtol, atol : float
        Converged when ``|r_free| <= rtol * scale + atol``, with ``scale`` the
        forces in play (member forces, applied loads and reactions; see
        :mod:`shellform.solvers.equilibrium`).
    roundoff_rtol : float
        Where the residual stalls at the rounding level of the member forces
        above that tolerance, the state still counts as converged while its
        largest entry is below this fraction of the largest force in play;
        otherwise the solve fails and says why.
    max_iter : int
        Newton iterations before giving up.
    merit : {"energy", "residual"}
        Line-search merit function. ``"residual"`` (half the squared residual
        norm) finds any equilibrium, stable or not. ``"energy"`` minimises the
        total potential: directions that do not descend are regularised, so it
        only finds stable equilibria but copes with slack ropes and mechanisms
        stabilised by load.
    linear_solver : {"direct", "amg", "auto"}
        See :mod:`shellform.solvers.linear`.
    max_backtracks : int
        Step halvings of the line search.
    project : bool
        When the full Newton step is rejected, also try the trial states
        moved back onto the linearised lengths of the axial members and the
        joint gaps (:class:`StretchProjection`) and keep the better ones
        (see the module docstring).
    """

    rtol: float = 1e-10
    atol: float = 1e-12
    roundoff_rtol: float = ROUNDOFF_RTOL
    max_iter: int = 100
    merit: str = "energy"
    linear_solver: str = "direct"
    max_backtracks: int = 30
    project: bool = True

    def __post_init__(self):
        if self.merit not in ("residual", "energy"):
            raise ValueError(f"merit must be 'residual' or 'energy', got {self.merit!r}")


def solve_static(
    system,
    q0: np.ndarray | None = None,
    lam: float = 1.0,
    mu: float = 0.0,
    *,
    options: NewtonOptions | None = None,
    callback=None,
    **overrides,
) -> StaticResult:
    """Find ``q`` with ``r(q, lam)[free] = 0`` by Newton's method.

    Parameters
    ----------
    system : System
        The assembled problem.
    q0 : ndarray, optional
        Starting state (all DOFs); constrained DOFs are overwritten with their
        prescribed values. Defaults to the reference state.
    lam : float
        Load factor multiplying the scaled loads.
    mu : float
        Prescribed-displacement parameter.
    options : NewtonOptions, optional
        Tolerances, merit, solver (defaults: :class:`NewtonOptions`).
    callback : callable, optional
        Called as ``callback(iteration, residual_norm)`` after every accepted
        step (progress display).
    **overrides
        Any field of :class:`NewtonOptions` by name (``rtol``, ``max_iter``, ...).

    Returns
    -------
    StaticResult
    """
    started = time.perf_counter()
    o = with_overrides(NewtonOptions, options, overrides, "Newton")
    q = system.state(mu=mu, base=q0)
    if not np.all(np.isfinite(q)):
        bad = int(np.flatnonzero(~np.isfinite(q))[0])
        raise ValueError(f"starting state has a non-finite value at DOF {bad} (node {bad // 3})")
    return _NewtonRun(system, lam, mu, o, started).solve(q, callback)


class _NewtonRun:
    """One static solve: its iterations, the equilibrium test of every iterate, and its result."""

    def __init__(self, system, lam: float, mu: float, o: NewtonOptions, started: float):
        self.system, self.lam, self.mu, self.o, self.started = system, lam, mu, o, started
        self.norms: list[float] = []
        self.regularised = 0
        self._play = (None, None)  # a state and its forces in play: one evaluation per state, not per test

    def evaluate(self, q):
        r = self.system.residual(q, self.lam)
        return r, float(np.linalg.norm(r[self.system.free]))

    def test(self, q, r, K=None):
        if self._play[0] is not q:
            self._play = (q, forces_in_play(self.system, q, self.lam))
        return check(self.system, q, self.lam, r, self.o, None if K is None else K.diagonal(), self._play[1])

    def solve(self, q, callback) -> StaticResult:
        """Newton iterations from ``q`` until the test is met, the residual stalls or no step is found."""
        o = self.o
        r, norm = self.evaluate(q)
        norms = self.norms
        norms.append(norm)
        eq = self.test(q, r)
        if not np.isfinite(norm):
            return self.result(q, eq, False, "residual is not finite at the starting state", 0)
        step = _Stepper(self.system, self.lam, o, self.evaluate)
        for it in range(1, o.max_iter + 1):
            if eq.converged:
                return self.result(q, eq, True, f"converged: {eq.describe()}", it - 1)
            K = self.system.tangent_free(q)
            eq = self.test(q, r, K)
            if eq.converged:
                return self.result(q, eq, True, f"converged: {eq.describe()}", it - 1)
            # near the rounding level a step can still gain a digit right after a fast
            # drop; once the residual stops falling, no iteration can help
            if eq.near_roundoff and len(norms) >= 2 and norms[-1] > 0.1 * norms[-2]:
                return self.stalled(q, eq, it - 1)
            taken = step(q, r, norm, K)
            if eq.near_roundoff and (taken is None or not taken[2] < norm):
                return self.stalled(q, eq, it - 1)
            if taken is None:
                return self.no_step(q, eq, K, step, it)
            q, r, norm = taken
            self.regularised = step.regularised
            norms.append(norm)
            if callback is not None:
                callback(it, norm)
            eq = self.test(q, r, K)
        if eq.converged:
            return self.result(q, eq, True, f"converged: {eq.describe()}", o.max_iter)
        if eq.near_roundoff:
            return self.stalled(q, eq, o.max_iter)
        return self.result(q, eq, False, f"not converged in {o.max_iter} iterations: {eq.describe()}", o.max_iter)

    def result(self, q, eq, success: bool, message: str, iterations: int) -> StaticResult:
        return StaticResult(
            q=q, success=success, message=message, iterations=iterations, residual_norms=self.norms,
            tolerance=eq.tolerance, lam=self.lam, mu=self.mu, reactions=self.system.reactions(q, self.lam),
            regularised_steps=self.regularised, wall_time_s=time.perf_counter() - self.started,
            forces_in_play=eq.scale,
        )

    def stalled(self, q, eq, iterations: int) -> StaticResult:
        """The end of a solve whose residual stopped falling near the rounding level."""
        if eq.acceptable_at_roundoff:
            return self.result(q, eq, True, f"converged: {eq.describe()}", iterations)
        return self.result(q, eq, False, f"iteration {iterations}: {eq.roundoff_failure()}", iterations)

    def no_step(self, q, eq, K, step: _Stepper, it: int) -> StaticResult:
        """The failure of iteration ``it``, where no shift of the tangent gave an acceptable step."""
        why = "the tangent is singular even with a large diagonal shift" if step.singular else (
            f"no step decreased the {self.o.merit} merit, even with a large diagonal shift")
        soft = (describe_soft_modes(self.system, K) if step.singular else "") or \
            "the structure may be a mechanism at this state"
        return self.result(q, eq, False, f"iteration {it}: {why} ({eq.describe()}); {soft}", it - 1)


class _Stepper:
    """One Newton step with its line search, regularised by diagonal shifts where the tangent asks for it.

    Counts the steps that needed a shift (``regularised``) and remembers whether
    the last failed step met only singular matrices (``singular``).
    """

    def __init__(self, system, lam: float, o: NewtonOptions, evaluate):
        self.system, self.lam, self.o, self.evaluate = system, lam, o, evaluate
        self.size = max(float(np.linalg.norm(np.ptp(system.structure.nodes, axis=0))), 1e-12)
        self.cache = {}  # the projections of all steps share one symbolic factorisation
        self.regularised = 0
        self.singular = False

    def __call__(self, q, r, norm, K):
        """``(q, r, |r|)`` after the step, or None when no shift gives an acceptable one."""
        system, o = self.system, self.o
        rf = r[system.free]
        phi0 = system.energy(q, self.lam) if o.merit == "energy" else 0.5 * norm**2
        # the energy is a sum of member terms, each known to the rounding of its force times the
        # rounding of the coordinates: a change below that cannot rank two states
        noise = (np.finfo(float).eps * self.size * float(np.sum(np.abs(system.forces_in_play(q, self.lam)[system.free])))
                 if o.merit == "energy" else 0.0)
        self.singular = True
        for shift in _shift_sequence(K, norm, self.size):
            try:
                A = K if shift == 0.0 else K + sp.diags(np.full(K.shape[0], shift))
                p = factorize(A, o.linear_solver).solve(-rf)
            except SingularMatrixError:
                continue
            self.singular = False
            slope = float(rf @ p) if o.merit == "energy" else -2.0 * phi0
            if slope >= 0.0:
                continue  # not a descent direction of the energy: shift further
            projection = (lambda q=q, p=p: StretchProjection(system, q, p, cache=self.cache)) if o.project else None
            q_try, r_try, norm_try = self.line_search(q, p, phi0, slope, norm, projection, noise)
            if q_try is not None:
                self.regularised += int(shift > 0.0)
                return q_try, r_try, norm_try
        return None

    def line_search(self, q, p, phi0, slope, norm, projection=None, noise: float = 0.0):
        """Backtracking (Armijo) along ``p``; returns (q, r, |r|) or (None, None, None).

        ``projection`` (a factory of a :class:`StretchProjection`): once the
        straight full step is rejected, every step length is tried both on the
        straight line and projected, and the trial with the lower merit counts.
        The projected trial wins where stiff members would be stretched by the
        rotation; the straight one where the members are soft enough for their
        length change to depart from the linearisation (compressed rods that
        buckle). The projection changes a trial state at second order in
        ``alpha``, so the slope of the Armijo test holds for both.
        """
        system, lam, merit, evaluate = self.system, self.lam, self.o.merit, self.evaluate
        free = system.free
        eps = np.finfo(float).eps

        def trial(alpha, project=None):
            """``[q, r, |r|, merit]``; under the energy merit the residual waits until it is needed."""
            q_try = q.copy()
            q_try[free] += alpha * p
            if project is not None:
                q_try = project(q_try, alpha)
            if merit == "energy":
                return [q_try, None, None, system.energy(q_try, lam)]
            r_try, norm_try = evaluate(q_try)
            return [q_try, r_try, norm_try, 0.5 * norm_try**2]

        def acceptable(c, alpha):
            phi = c[3]
            if not np.isfinite(phi):
                return False
            armijo = phi <= phi0 + 1e-4 * alpha * slope
            # close to a minimum the energy changes less than its round-off (``noise``, from the
            # forces in play) and cannot rank steps; the residual norm still can
            flat = merit == "energy" and abs(phi - phi0) <= 1e3 * (eps * (abs(phi0) + abs(slope)) + noise)
            if not (armijo or flat):
                return False
            if c[1] is None:
                c[1], c[2] = evaluate(c[0])
            if not np.isfinite(c[2]):
                return False
            return bool(armijo or c[2] < (1.0 - 1e-4 * alpha) * norm)

        project = None
        alpha = 1.0
        for k in range(self.o.max_backtracks):
            candidates = [trial(alpha)]
            if k == 0 and projection is not None and not acceptable(candidates[0], alpha):
                project = projection()
            if project is not None:
                candidates.append(trial(alpha, project))
            # the better of the straight and the projected trial
            best = min(candidates, key=lambda c: c[3] if np.isfinite(c[3]) else np.inf)
            if acceptable(best, alpha):
                return best[0], best[1], best[2]
            alpha *= 0.5
        return None, None, None


class StretchProjection:
    """Trial states of a Newton step moved back onto the linearised values of the held measures.

    A Newton step ``p`` from ``q`` changes each held measure ``m`` (the length
    of an axially stiff member, :meth:`~shellform.effects.base.Effect.held_measures`)
    by ``J p`` to first order; a straight step ``q + alpha p`` that rotates a
    member lengthens it by a further ``alpha^2 |p_perp|^2 / (2 l)``, which a
    stiff member turns into a large spurious energy. The projection finds the
    smallest correction ``d`` (Gauss-Newton on ``m(q + alpha p + d) = m(q) +
    alpha J p``, minimum norm: ``d = -J^T (J J^T)^{-1} g``) and so follows the
    rotation instead of its tangent line. Without held measures it is the
    identity.

    Parameters
    ----------
    system : System
    q : ndarray
        State at the start of the step (all DOFs).
    p : ndarray
        Newton step on the free DOFs.
    rtol : float
        Measures are projected to ``rtol`` times the largest of them.
    max_iter : int
        Gauss-Newton iterations per projection.
    cache : dict, optional
        Shared by the projections of one solve: the ``J J^T`` of every
        projection has the same pattern, so its ordering and symbolic
        factorisation are reused.
    """

    def __init__(self, system, q: np.ndarray, p: np.ndarray, rtol: float = 1e-13, max_iter: int = 6,
                 cache: dict | None = None):
        self.system = system
        self.max_iter = max_iter
        self._cache = {} if cache is None else cache
        held = system.held_measures(q) if hasattr(system, "held_measures") else None
        if held is None or held[0].size == 0:
            self.m0 = None
            return
        m0, J = held
        self.m0 = m0
        self.dm = J @ p
        self.tol = rtol * float(np.max(np.abs(m0)))

    def __call__(self, q_trial: np.ndarray, alpha: float) -> np.ndarray:
        """The projected trial state.

        Stops when the measures meet their targets, or stagnate (redundant
        measures, e.g. a triangulated bar lattice, can only be met in the
        least-squares sense); ``q_trial`` itself when the projection fails.
        """
        if self.m0 is None:
            return q_trial
        free = self.system.free
        target = self.m0 + alpha * self.dm
        q = q_trial.copy()
        best, best_gap = q_trial, np.inf
        for _ in range(self.max_iter + 1):
            m, J = self.system.held_measures(q)
            gap = float(np.max(np.abs(m - target)))
            if not np.isfinite(gap) or gap > 0.5 * best_gap:
                break
            best, best_gap = q.copy(), gap
            if gap <= self.tol:
                break
            A = sp.csr_matrix(J @ J.T)
            # redundant measures make J J^T singular: a tiny shift gives the
            # least-squares correction
            A = A + sp.diags(np.full(A.shape[0], 1e-12 * float(A.diagonal().max())))
            try:
                F = LDLFactor(A, previous=self._cache.get("factor"))
                self._cache["factor"] = F
                q[free] -= J.T @ F.solve(m - target)
            except SingularMatrixError:
                self._cache.pop("factor", None)
                break
        return best
