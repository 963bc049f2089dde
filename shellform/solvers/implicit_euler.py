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
from .equilibrium import ROUNDOFF_RTOL
from .implicit_step import Stepper, as_function
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
    first_step : float, optional
        Size of the first step [s] (default ``h``); later steps grow back to
        ``h`` by doubling. A start far from equilibrium (a structure pushed
        off a critical state) takes a small first step instead of failing
        the large ones first.
    hold_after_reject : int
        After a step is retried with a smaller time step, this many accepted
        steps keep the reduced size before it grows again (0: it doubles after
        every accepted step). A size that has just failed tends to fail again
        right away.
    linear_solver : str
        See :mod:`shellform.solvers.linear`.
    keep_factor : bool
        Keep the factor of the last Newton iteration's Jacobian and start the
        next step of the same size with chord iterations on it (one residual
        and one solve each, no tangent and no factorisation) while each
        divides the residual by at least ``1 / CHORD_RATE`` (:mod:`.implicit_step`); Newton takes over
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
    first_step: float | None = None
    hold_after_reject: int = 0
    linear_solver: str = "direct"
    save_every: int = 0
    keep_factor: bool = True


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


def _first_step(h: float, t0: float, t_end: float, o: ImplicitEulerOptions) -> float:
    """The first time step, after checking the time inputs."""
    if not (np.isfinite(h) and h > 0):
        raise ModelError(f"implicit Euler: time step must be positive, got {h}")
    if not (np.isfinite(t_end) and t_end > t0):
        raise ModelError(f"implicit Euler: t_end must be after t0 = {t0}, got {t_end}")
    if o.first_step is None:
        return h
    if not (np.isfinite(o.first_step) and o.first_step > 0):
        raise ModelError(f"implicit Euler: first_step must be positive, got {o.first_step}")
    return min(h, float(o.first_step))


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
        ``callback(t, q, v)`` after every accepted step (progress, checkpoints).
        Returning True marks the state as a restart point (a checkpoint was
        written there): the next step then starts without the kept factor,
        as a run resumed from that state does, so that both go on alike.
    **overrides
        Any field of :class:`ImplicitEulerOptions` by name (``mass``,
        ``damping``, ``mu``, ``rtol``, ``stop``, ...), applied on top of ``options``.

    Returns
    -------
    DynamicResult
    """
    started = time.perf_counter()
    o = with_overrides(ImplicitEulerOptions, options, overrides, "implicit Euler")
    dt = _first_step(h, t0, t_end, o)
    mass, damping = _mass_and_damping(system, o)
    stepper = Stepper(system, o, mass, damping)
    min_step = h / 1024.0 if o.min_step is None else float(o.min_step)
    q = stepper.supports(system.state(base=q0), t0)
    v = np.zeros(system.n_dof) if v0 is None else np.array(v0, dtype=float)
    t = t0
    hold = 0  # accepted steps left before the step may grow again
    run = _Trajectory(q, v, t, mass, o.save_every, started)
    while t_end - t > 1e-9 * h:
        # the last step takes the remainder, never a sliver of a step after it (a step of
        # 1e-14 s makes the inertia terms M / dt^2 large enough to drown every force)
        dt = t_end - t if t_end - t <= dt * (1.0 + 1e-6) else dt
        q_new, r, its = stepper.step(q, v, t + dt, dt)
        if q_new is None:
            run.res.rejected_steps += 1
            dt *= 0.5
            hold = o.hold_after_reject
            if dt < min_step:
                return run.end(q, v, t, False, f"time step fell below {min_step:.3g} s at t = {t:.6g} s: {r}")
            continue
        v = (q_new - q) / dt
        q = q_new
        t += dt
        system.accept(q)
        static = run.record(t, q, v, r[system.free], its)
        if callback is not None and callback(t, q, v):
            stepper.kept = None
        if o.stop is not None and o.stop(t, q, v, static):
            return run.end(q, v, t, True, f"stopped at t = {t:.6g} s after {run.res.steps} steps")
        if hold > 0:
            hold -= 1
        else:
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
    lam_f = as_function(o.lam)

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
