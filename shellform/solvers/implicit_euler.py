"""Implicit Euler time stepping with Newton iterations (Eq. 2 of the gridshell paper).

With the lumped mass matrix ``M`` (nodal masses on translations, rotational
inertia on twist angles), mass-proportional viscous damping ``C = c M`` and
the residual of the System ``r(q, lam) = f_int(q) - f_ext(lam)``, a step of
size ``h`` from ``(q_k, v_k)`` solves

    M (dq - h v_k) / h^2 + C dq / h + r(q_k + dq, lam_{k+1}) = 0,      (Eq. 2a / h^2)
    q_{k+1} = q_k + dq,   v_{k+1} = dq / h,                              (Eqs. 2b, 2c)

for the free DOFs, with the constrained DOFs at their prescribed values at
``t_{k+1}``. The left side is the gradient of the incremental potential

    Phi(dq) = |dq - h v_k|_M^2 / (2 h^2) + |dq|_C^2 / (2 h) + Pi(q_k + dq, lam),

so each step is a minimisation: Newton with the Jacobian ``M/h^2 + C/h + K``,
a backtracking line search on ``Phi``, and a diagonal shift when the Jacobian
is not positive definite (past a snap the tangent ``K`` is indefinite, the
inertia term usually restores definiteness for small ``h``). A step whose
Newton iterations fail is retried with half the time step.

After every converged step the System accepts the new state, so the rods'
reference frames are carried along the trajectory by time-parallel transport.

With damping, the motion dies out and the state approaches a stable
equilibrium: :func:`relax_to_rest` runs the scheme as dynamic relaxation until the
static residual and the velocity vanish.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from ..errors import ModelError
from .equilibrium import ROUNDOFF_RTOL, EquilibriumCheck, forces_in_play, roundoff_level
from .linear import SingularMatrixError, factorize, shift_diagonal
from .options import with_overrides


def lumped_mass(structure, network=None) -> np.ndarray:
    """Diagonal of the lumped mass matrix over all DOFs.

    Translations get the structure's nodal masses (members and point masses);
    twist angles get the rotational inertia of their rod edge when a rod
    network is given (zero otherwise).
    """
    m = np.zeros(structure.n_dof)
    m[: 3 * structure.n_nodes] = np.repeat(structure.nodal_mass(), 3)
    if network is not None and len(network.rods):
        m[network.edge_twist] = network.rotational_inertia
    return m


@dataclass
class DynamicResult:
    """Outcome of a time integration.

    Attributes
    ----------
    q, v : ndarray
        State and velocity at the last accepted step.
    t : float
        Time reached.
    success : bool
    message : str
    steps : int
        Accepted steps.
    rejected_steps : int
        Steps retried with a smaller time step.
    newton_iterations : list of int
        Newton iterations of every accepted step.
    times, kinetic_energy, residual_norms : ndarray
        History at every accepted step: time, kinetic energy ``1/2 v.Mv`` and
        norm of the static residual ``r(q)`` at the free DOFs.
    states : list of (t, q)
        States saved every ``save_every`` steps.
    wall_time_s : float
    """

    q: np.ndarray
    v: np.ndarray
    t: float
    success: bool
    message: str
    steps: int = 0
    rejected_steps: int = 0
    newton_iterations: list[int] = field(default_factory=list)
    times: np.ndarray = field(default_factory=lambda: np.zeros(0))
    kinetic_energy: np.ndarray = field(default_factory=lambda: np.zeros(0))
    residual_norms: np.ndarray = field(default_factory=lambda: np.zeros(0))
    states: list = field(default_factory=list)
    wall_time_s: float = 0.0

    @property
    def residual_norm(self) -> float:
        return float(self.residual_norms[-1]) if self.residual_norms.size else float("nan")


@dataclass(frozen=True)
class ImplicitEulerOptions:
    """Options of :func:`implicit_euler`: what drives and damps the motion, and how each step is solved.

    Attributes
    ----------
    mass : ndarray (n_dof,), optional
        Lumped masses; default :func:`lumped_mass` of the structure (twist
        DOFs massless unless a rod network's inertia is given through
        ``lumped_mass(structure, network)``).
    damping : float or ndarray (n_dof,)
        Mass-proportional coefficient ``c`` [1/s] (``C = c M``), or the
        diagonal of ``C`` itself when an array.
    lam, mu : float or callable
        Load factor and prescribed-displacement parameter, constant or as
        functions of time.
    paths : sequence of NodePath
        Supports moved along paths (``path(t)``).
    stop : callable, optional
        ``stop(t, q, v, static_residual_norm) -> bool``: end early (success).
    rtol, atol : float
        Newton tolerance on the step residual (force units), relative to
        the external, inertial and reaction forces.
    roundoff_rtol : float
        Largest step residual, relative to the largest force in play,
        accepted where round-off stops the Newton iterations
        (:mod:`shellform.solvers.equilibrium`).
    max_newton : int
        Newton iterations of a step before it is retried with half the time step.
    min_step : float, optional
        Smallest time step [s] a failing step is halved down to (default ``h / 1024``).
    linear_solver : str
        See :mod:`shellform.solvers.linear`.
    keep_factor : bool
        Keep the factor of the last Newton iteration's Jacobian and start the
        next step of the same size with chord iterations on it (one residual
        and one solve each, no tangent and no factorisation) while each
        divides the residual by at least ``1 / CHORD_RATE``; Newton takes over
        otherwise. The converged state meets the same tolerance.
    save_every : int
        Keep every ``save_every``-th state in ``result.states`` (0: none).
    """

    mass: np.ndarray | None = None
    damping: float | np.ndarray = 0.0
    lam: float | Callable[[float], float] = 1.0
    mu: float | Callable[[float], float] = 0.0
    paths: Sequence = ()
    stop: Callable[[float, np.ndarray, np.ndarray, float], bool] | None = None
    rtol: float = 1e-9
    atol: float = 1e-12
    roundoff_rtol: float = ROUNDOFF_RTOL
    max_newton: int = 25
    min_step: float | None = None
    linear_solver: str = "direct"
    save_every: int = 0
    keep_factor: bool = True


#: A chord iteration with a kept factor must divide the step's residual by 1 / CHORD_RATE, or
#: Newton takes over (``benchmarks/bench_hemisphere.py --chord-rates``).
CHORD_RATE = 0.1


def _as_function(value) -> Callable[[float], float]:
    if callable(value):
        return value
    v = float(value)
    return lambda t: v


def _max_abs(v: np.ndarray) -> float:
    return float(np.max(np.abs(v), initial=0.0))


class _Stepper:
    """One implicit Euler step: Newton on the incremental potential of the free DOFs."""

    def __init__(self, system, options: ImplicitEulerOptions, mass: np.ndarray, damping: np.ndarray):
        self.system = system
        self.o = options
        self.mass, self.damping = mass, damping
        self.lam, self.mu = _as_function(options.lam), _as_function(options.mu)
        self.paths = tuple(options.paths)
        self.kept = None  # (h, factor) of the last unshifted Jacobian

    def supports(self, q, t):
        """``q`` with the constrained DOFs at their values at time ``t``."""
        q = self.system.state(mu=self.mu(t), base=q)
        for p in self.paths:
            q[p.dofs] = p(t)
        return q

    def step(self, q_k, v_k, t_next, h):
        """Returns (q, r, iterations) or (None, message, iterations)."""
        pb = _StepPotential(self, q_k, v_k, t_next, h)
        q = self.supports(q_k + h * v_k, t_next)  # explicit predictor; supports exact
        r, R = pb.residual(q)
        norm = previous = float(np.linalg.norm(R))
        max_iter = self.o.max_newton
        done, phi = 0, None
        # chord iterations with the kept factor of an earlier step of the same size, while they converge fast
        while self.kept is not None and self.kept[0] == h and done < max_iter:
            if pb.met(R, r):
                return q, r, done
            phi = pb.merit(q) if phi is None else phi
            taken = self._chord(pb, self.kept[1], q, R, norm, phi)
            if taken is None:
                break
            done += 1
            previous = norm
            q, r, R, norm, phi = taken
            if norm > CHORD_RATE * previous:
                break
        for it in range(done + 1, max_iter + 1):
            if it > 1 and pb.met(R, r):
                # converged by the tolerance alone: no tangent is needed to say so (the
                # round-off floor of the full test, which needs the tangent's diagonal, only widens it)
                return q, r, it - 1
            J = pb.jacobian(q)
            eq = pb.test(q, r, R, J)
            if eq.converged:
                return q, r, it - 1
            if eq.near_roundoff and it > 1 and norm > 0.1 * previous:
                return _stalled(eq, q, r, it - 1)
            taken = self._descend(pb, q, R, J, norm)
            if eq.near_roundoff and (taken is None or not taken[3] < norm):
                return _stalled(eq, q, r, it - 1)
            if taken is None:
                return None, f"Newton iteration {it}: no step decreased the incremental potential", it
            previous = norm
            q, r, R, norm = taken
        eq = pb.test(q, r, R, pb.jacobian(q))
        if eq.converged:
            return q, r, max_iter
        if eq.near_roundoff:
            return _stalled(eq, q, r, max_iter)
        return None, f"Newton did not converge in {max_iter} iterations ({eq.describe()})", max_iter

    def _chord(self, pb, F, q, R, norm, phi):
        """A full step with the kept factor ``F`` when it lowers the incremental potential (``phi`` at
        ``q``) and the residual: ``(q, r, R, |R|, phi)`` after it, else None."""
        try:
            p = F.solve(-R)
        except SingularMatrixError:
            return None
        slope = float(R @ p)
        if not slope < 0.0:
            return None
        q_try = q.copy()
        q_try[pb.free] += p
        r_try, R_try = pb.residual(q_try)
        n_try = float(np.linalg.norm(R_try))
        if not (np.isfinite(n_try) and n_try < norm):
            return None
        phi_try = pb.merit(q_try)
        if not phi_try <= phi + 1e-4 * slope:
            return None
        return q_try, r_try, R_try, n_try, phi_try

    def _descend(self, pb, q, R, J, norm):
        """The Newton step from ``q``, shifted until it lowers the incremental potential:
        ``(q, r, R, |R|)`` after it, or None when no shift gives one."""
        phi0 = pb.merit(q)
        diag = np.abs(J.diagonal())
        base_shift = float(np.mean(diag[diag > 0])) if np.any(diag > 0) else 1.0
        self.kept = None  # freed first: the new factorisation takes over its symbolic analysis
        for shift in [0.0] + [base_shift * 10.0**k for k in range(-8, 4)]:
            A = J if shift == 0.0 else shift_diagonal(J, shift)
            try:
                F = factorize(A, self.o.linear_solver)
                p = F.solve(-R)
            except SingularMatrixError:
                continue
            if shift == 0.0 and self.o.keep_factor:
                self.kept = (pb.h, F)
            slope = float(R @ p)
            if slope >= 0.0:
                continue
            taken = pb.backtrack(q, p, phi0, slope, norm)
            if taken is not None:
                return taken
        return None


def _stalled(eq: EquilibriumCheck, q, r, iterations):
    """The end of a step whose residual stopped falling near the rounding level."""
    if eq.acceptable_at_roundoff:
        return q, r, iterations
    return None, f"Newton iteration {iterations}: {eq.roundoff_failure()}", iterations


class _StepPotential:
    """The incremental potential of one step of size ``h`` from ``(q_k, v_k)``, its gradient and equilibrium test.

    ``Phi(dq) = |dq - h v_k|_M^2 / (2 h^2) + |dq|_C^2 / (2 h) + Pi(q_k + dq, lam)`` over
    the free DOFs (module docstring).
    """

    def __init__(self, stepper: _Stepper, q_k, v_k, t_next, h):
        system, free = stepper.system, stepper.system.free
        self.system, self.o, self.free = system, stepper.o, free
        self.lam = stepper.lam(t_next)
        self.Mf, self.Cf = stepper.mass[free], stepper.damping[free]
        self.jac_diag = self.Mf / h**2 + self.Cf / h
        self.base, self.hv, self.h = q_k.copy(), h * v_k[free], h
        # forces in play: loads, the inertia of the motion, and the member forces at the
        # step's start (the scale changes little within a step, and is computed once, when
        # the loads and the inertia alone are too small a scale to accept the step)
        ext = system.external_force(self.lam)
        inertia = self.Mf * v_k[free] / h
        self.applied = float(np.linalg.norm(ext))
        self.loads = max(self.applied, float(np.linalg.norm(inertia)))
        self.loads_max = max(_max_abs(ext), _max_abs(inertia))
        self._in_play = None

    @property
    def in_play(self) -> tuple[float, float]:
        """Norm and largest entry of the forces in play (the member forces at the step's start included)."""
        if self._in_play is None:
            play = forces_in_play(self.system, self.base, self.lam)
            self._in_play = (max(self.loads, play[0]), max(self.loads_max, play[1]))
        return self._in_play

    def merit(self, q):
        dq = (q - self.base)[self.free]
        a = dq - self.hv
        return (0.5 * float(a @ (self.Mf * a)) / self.h**2 + 0.5 * float(dq @ (self.Cf * dq)) / self.h
                + self.system.energy(q, self.lam))

    def residual(self, q):
        """The static residual ``r`` (all DOFs) and the step's residual ``R`` (free DOFs)."""
        r = self.system.residual(q, self.lam)
        dq = (q - self.base)[self.free]
        R = self.Mf * (dq - self.hv) / self.h**2 + self.Cf * dq / self.h + r[self.free]
        return r, R

    def jacobian(self, q):
        return shift_diagonal(self.system.tangent_free(q), self.jac_diag)

    def met(self, R, r) -> bool:
        """Whether ``R`` meets the tolerance (what :meth:`test` calls ``met``), without the tangent."""
        norm = float(np.linalg.norm(R))
        reactions = float(np.linalg.norm(r[self.system.constrained]))
        if norm <= self.o.rtol * max(self.loads, reactions) + self.o.atol:
            return True  # the member forces could only widen the scale
        return norm <= self.o.rtol * max(self.in_play[0], reactions) + self.o.atol

    def test(self, q, r, R, J) -> EquilibriumCheck:
        reactions = r[self.system.constrained]
        scale = max(self.in_play[0], float(np.linalg.norm(reactions)))
        scale_max = max(self.in_play[1], _max_abs(reactions))
        return EquilibriumCheck(float(np.linalg.norm(R)), scale, self.o.rtol * scale + self.o.atol,
                                roundoff_level(J.diagonal(), q), self.o.roundoff_rtol, self.applied,
                                _max_abs(R), scale_max)

    def backtrack(self, q, p, phi0, slope, norm):
        """Halve the step ``p`` from ``q`` until the potential falls enough: ``(q, r, R, |R|)``, or None."""
        eps = np.finfo(float).eps
        alpha = 1.0
        for _ in range(30):
            q_try = q.copy()
            q_try[self.free] += alpha * p
            r_try, R_try = self.residual(q_try)
            n_try = float(np.linalg.norm(R_try))
            if np.isfinite(n_try):
                phi = self.merit(q_try)
                if phi <= phi0 + 1e-4 * alpha * slope:
                    return q_try, r_try, R_try, n_try
                # at round-off level Phi cannot rank steps; the residual still can
                if abs(phi - phi0) <= 1e3 * eps * (abs(phi0) + abs(slope)) and n_try < norm:
                    return q_try, r_try, R_try, n_try
            alpha *= 0.5
        return None


def _mass_and_damping(system, o: ImplicitEulerOptions) -> tuple[np.ndarray, np.ndarray]:
    """The diagonals of ``M`` and ``C`` over all DOFs, checked."""
    n = system.n_dof
    mass = lumped_mass(system.structure) if o.mass is None else np.asarray(o.mass, dtype=float)
    if mass.shape != (n,) or np.any(mass < 0) or not np.all(np.isfinite(mass)):
        raise ModelError(f"implicit Euler: mass must be {n} finite non-negative values")
    damping = np.asarray(o.damping, dtype=float)
    C = damping * mass if damping.ndim == 0 else damping
    if C.shape != (n,) or np.any(C < 0) or not np.all(np.isfinite(C)):
        raise ModelError(f"implicit Euler: damping must be a non-negative coefficient or {n} values")
    return mass, C


class _Trajectory:
    """The accepted steps of a run: the counts and histories that become its :class:`DynamicResult`."""

    def __init__(self, q, v, t, mass, save_every, started):
        self.res = DynamicResult(q=q, v=v, t=t, success=False, message="")
        self.mass, self.save_every, self.started = mass, save_every, started
        self.times, self.kinetic, self.resid = [], [], []

    def record(self, t, q, v, r_free, iterations) -> float:
        """Count an accepted step ending at ``(t, q, v)``; the norm of its static residual."""
        res = self.res
        res.steps += 1
        res.newton_iterations.append(iterations)
        static = float(np.linalg.norm(r_free))
        self.times.append(t)
        self.kinetic.append(0.5 * float(v @ (self.mass * v)))
        self.resid.append(static)
        if self.save_every and res.steps % self.save_every == 0:
            res.states.append((t, q.copy()))
        return static

    def end(self, q, v, t, success: bool, message: str) -> DynamicResult:
        res = self.res
        res.q, res.v, res.t = q, v, t
        res.success, res.message = success, message
        res.times = np.array(self.times)
        res.kinetic_energy = np.array(self.kinetic)
        res.residual_norms = np.array(self.resid)
        res.wall_time_s = time.perf_counter() - self.started
        return res


def implicit_euler(
    system,
    h: float,
    t_end: float,
    q0: np.ndarray | None = None,
    v0: np.ndarray | None = None,
    *,
    t0: float = 0.0,
    options: ImplicitEulerOptions | None = None,
    callback: Callable[[float, np.ndarray, np.ndarray], None] | None = None,
    **overrides,
) -> DynamicResult:
    """Integrate ``M a + C v + r(q, lam(t)) = 0`` by implicit Euler from ``t0`` to ``t_end``.

    Parameters
    ----------
    system : System
    h : float
        Time step [s]. A step whose Newton iterations fail is halved (down
        to ``min_step``, default ``h / 1024``) and grown back afterwards.
    t_end : float
        Final time [s].
    q0, v0 : ndarray, optional
        Initial state (default reference) and velocity (default zero).
    t0 : float
        Initial time [s].
    options : ImplicitEulerOptions, optional
        Masses, damping, loads and supports in time, tolerances, solver
        (defaults: :class:`ImplicitEulerOptions`).
    callback : callable, optional
        ``callback(t, q, v)`` after every accepted step (progress).
    **overrides
        Any field of :class:`ImplicitEulerOptions` by name (``mass``,
        ``damping``, ``mu``, ``rtol``, ``stop``, ...), applied on top of ``options``.

    Returns
    -------
    DynamicResult
    """
    started = time.perf_counter()
    o = with_overrides(ImplicitEulerOptions, options, overrides, "implicit Euler")
    if not (np.isfinite(h) and h > 0):
        raise ModelError(f"implicit Euler: time step must be positive, got {h}")
    if not (np.isfinite(t_end) and t_end > t0):
        raise ModelError(f"implicit Euler: t_end must be after t0 = {t0}, got {t_end}")
    mass, damping = _mass_and_damping(system, o)
    stepper = _Stepper(system, o, mass, damping)
    min_step = h / 1024.0 if o.min_step is None else float(o.min_step)
    q = stepper.supports(system.state(base=q0), t0)
    v = np.zeros(system.n_dof) if v0 is None else np.array(v0, dtype=float)
    t, dt = t0, h
    run = _Trajectory(q, v, t, mass, o.save_every, started)
    while t_end - t > 1e-9 * h:
        # the last step takes the remainder, never a sliver of a step after it (a step of
        # 1e-14 s makes the inertia terms M / dt^2 large enough to drown every force)
        dt = t_end - t if t_end - t <= dt * (1.0 + 1e-6) else dt
        q_new, r, its = stepper.step(q, v, t + dt, dt)
        if q_new is None:
            run.res.rejected_steps += 1
            dt *= 0.5
            if dt < min_step:
                return run.end(q, v, t, False, f"time step fell below {min_step:.3g} s at t = {t:.6g} s: {r}")
            continue
        v = (q_new - q) / dt
        q = q_new
        t += dt
        system.accept(q)
        static = run.record(t, q, v, r[system.free], its)
        if callback is not None:
            callback(t, q, v)
        if o.stop is not None and o.stop(t, q, v, static):
            return run.end(q, v, t, True, f"stopped at t = {t:.6g} s after {run.res.steps} steps")
        dt = min(h, 2.0 * dt)
    return run.end(q, v, t, True, f"reached t = {t:.6g} s in {run.res.steps} steps")


def relax_to_rest(
    system,
    h: float,
    damping: float,
    t_max: float,
    q0: np.ndarray | None = None,
    *,
    force_tol: float = 1e-8,
    velocity_tol: float | None = None,
    options: ImplicitEulerOptions | None = None,
    **overrides,
) -> DynamicResult:
    """Dynamic relaxation: damped implicit Euler until the structure is at rest in equilibrium.

    Stops (success) when the static residual at the free DOFs is below
    ``force_tol`` times the external force (or the reaction force, whichever
    is larger) and the largest velocity is below ``velocity_tol`` (default:
    ``force_tol`` times the model size per unit time); fails if ``t_max``
    passes first. Loads and supports are held at their values at ``t_max``
    when ``lam``/``mu`` are constants. ``options`` and ``overrides`` are those
    of :func:`implicit_euler`; the stop criterion is this function's own.
    """
    o = with_overrides(ImplicitEulerOptions, options, dict(overrides, damping=damping), "implicit Euler")
    size = max(float(np.linalg.norm(np.ptp(system.structure.nodes, axis=0))), 1e-12)
    vtol = force_tol * size if velocity_tol is None else velocity_tol
    lam_f = _as_function(o.lam)

    def stop(t, q, v, static):
        scale = max(float(np.linalg.norm(system.external_force(lam_f(t)))),
                    float(np.linalg.norm(system.residual(q, lam_f(t))[system.constrained])), 1e-300)
        return static <= force_tol * scale and float(np.abs(v).max()) <= vtol

    res = implicit_euler(system, h, t_max, q0=q0, options=dataclasses.replace(o, stop=stop))
    if res.success and res.t >= t_max - 1e-12 * h and not stop(res.t, res.q, res.v, res.residual_norm):
        res.success = False
        res.message = (
            f"not at rest by t = {t_max:.6g} s: static residual {res.residual_norm:.3e}, "
            f"largest velocity {float(np.abs(res.v).max()):.3e}"
        )
    return res
