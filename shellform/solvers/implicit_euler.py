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
equilibrium: :func:`relax` runs the scheme as dynamic relaxation until the
static residual and the velocity vanish.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from ..errors import ModelError
from .equilibrium import ROUNDOFF_RTOL, EquilibriumCheck, forces_in_play, roundoff_level
from .linear import SingularMatrixError, factorize


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


def _as_function(value) -> Callable[[float], float]:
    if callable(value):
        return value
    v = float(value)
    return lambda t: v


class _Stepper:
    """One implicit Euler step: Newton on the incremental potential of the free DOFs."""

    def __init__(self, system, mass, damping, lam, mu, paths, rtol, atol, max_iter, linear_solver):
        self.system = system
        self.free = system.free
        self.mass = mass
        self.damping = damping
        self.lam = lam
        self.mu = mu
        self.paths = tuple(paths)
        self.rtol, self.atol = rtol, atol
        self.roundoff_rtol = ROUNDOFF_RTOL
        self.max_iter = max_iter
        self.linear_solver = linear_solver
        self.size = max(float(np.linalg.norm(np.ptp(system.structure.nodes, axis=0))), 1e-12)

    def supports(self, q, t):
        """``q`` with the constrained DOFs at their values at time ``t``."""
        q = self.system.state(mu=self.mu(t), base=q)
        for p in self.paths:
            q[p.dofs] = p(t)
        return q

    def step(self, q_k, v_k, t_next, h):
        """Returns (q, r, iterations) or (None, message, iterations)."""
        sysm, free = self.system, self.free
        lam = self.lam(t_next)
        M, C = self.mass, self.damping
        Mf, Cf = M[free], C[free]
        jac_diag = Mf / h**2 + Cf / h
        q = self.supports(q_k + h * v_k, t_next)  # explicit predictor; supports exact
        base = q_k.copy()

        def merit(qq):
            dq = (qq - base)[free]
            a = dq - h * v_k[free]
            return 0.5 * float(a @ (Mf * a)) / h**2 + 0.5 * float(dq @ (Cf * dq)) / h + sysm.energy(qq, lam)

        def residual(qq):
            r = sysm.residual(qq, lam)
            dq = (qq - base)[free]
            R = Mf * (dq - h * v_k[free]) / h**2 + Cf * dq / h + r[free]
            return r, R

        # forces in play: loads, the inertia of the motion, and the member forces at the
        # step's start (the scale changes little within a step, and is computed once)
        ext = sysm.external_force(lam)
        inertia = Mf * v_k[free] / h
        play = forces_in_play(sysm, q_k, lam)
        in_play = max(float(np.linalg.norm(ext)), float(np.linalg.norm(inertia)), play[0])
        in_play_max = max(float(np.max(np.abs(ext), initial=0.0)), float(np.max(np.abs(inertia), initial=0.0)), play[1])

        def test(r, R, J):
            reactions = r[sysm.constrained]
            scale = max(in_play, float(np.linalg.norm(reactions)))
            scale_max = max(in_play_max, float(np.max(np.abs(reactions), initial=0.0)))
            return EquilibriumCheck(float(np.linalg.norm(R)), scale, self.rtol * scale + self.atol,
                                    roundoff_level(J.diagonal(), q), self.roundoff_rtol, float(np.linalg.norm(ext)),
                                    float(np.max(np.abs(R), initial=0.0)), scale_max)

        def stalled(eq, it):
            if eq.acceptable_at_roundoff:
                return q, r, it
            return None, f"Newton iteration {it}: {eq.roundoff_failure()}", it

        r, R = residual(q)
        norm = previous = float(np.linalg.norm(R))
        eps = np.finfo(float).eps
        for it in range(1, self.max_iter + 1):
            K = sysm.tangent_free(q)
            J = K + sp.diags(jac_diag)
            eq = test(r, R, J)
            if eq.converged:
                return q, r, it - 1
            if eq.near_roundoff and it > 1 and norm > 0.1 * previous:
                return stalled(eq, it - 1)
            phi0 = merit(q)
            diag = np.abs(J.diagonal())
            base_shift = float(np.mean(diag[diag > 0])) if np.any(diag > 0) else 1.0
            moved = False
            for shift in [0.0] + [base_shift * 10.0**k for k in range(-8, 4)]:
                A = J if shift == 0.0 else J + sp.diags(np.full(J.shape[0], shift))
                try:
                    p = factorize(A, self.linear_solver).solve(-R)
                except SingularMatrixError:
                    continue
                slope = float(R @ p)
                if slope >= 0.0:
                    continue
                alpha = 1.0
                for _ in range(30):
                    q_try = q.copy()
                    q_try[free] += alpha * p
                    r_try, R_try = residual(q_try)
                    n_try = float(np.linalg.norm(R_try))
                    if np.isfinite(n_try):
                        phi = merit(q_try)
                        if phi <= phi0 + 1e-4 * alpha * slope:
                            moved = True
                            break
                        # at round-off level Phi cannot rank steps; the residual still can
                        if abs(phi - phi0) <= 1e3 * eps * (abs(phi0) + abs(slope)) and n_try < norm:
                            moved = True
                            break
                    alpha *= 0.5
                if moved:
                    break
            if eq.near_roundoff and (not moved or not n_try < norm):
                return stalled(eq, it - 1)
            if not moved:
                return None, f"Newton iteration {it}: no step decreased the incremental potential", it
            previous = norm
            q, r, R, norm = q_try, r_try, R_try, n_try
        eq = test(r, R, sysm.tangent_free(q) + sp.diags(jac_diag))
        if eq.converged:
            return q, r, self.max_iter
        if eq.near_roundoff:
            return stalled(eq, self.max_iter)
        return None, f"Newton did not converge in {self.max_iter} iterations ({eq.describe()})", self.max_iter


def implicit_euler(
    system,
    h: float,
    t_end: float,
    q0: np.ndarray | None = None,
    v0: np.ndarray | None = None,
    mass: np.ndarray | None = None,
    damping=0.0,
    lam=1.0,
    mu=0.0,
    paths: Sequence = (),
    t0: float = 0.0,
    rtol: float = 1e-9,
    atol: float = 1e-12,
    max_newton: int = 25,
    min_step: float | None = None,
    linear_solver: str = "direct",
    stop: Callable[[float, np.ndarray, np.ndarray, float], bool] | None = None,
    save_every: int = 0,
    callback: Callable[[float, np.ndarray, np.ndarray], None] | None = None,
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
    rtol, atol : float
        Newton tolerance on the step residual (force units), relative to
        the external, inertial and reaction forces.
    stop : callable, optional
        ``stop(t, q, v, static_residual_norm) -> bool``: end early (success).
    save_every : int
        Keep every ``save_every``-th state in ``result.states`` (0: none).
    callback : callable, optional
        ``callback(t, q, v)`` after every accepted step (progress).

    Returns
    -------
    DynamicResult
    """
    start = time.perf_counter()
    if not (np.isfinite(h) and h > 0):
        raise ModelError(f"implicit Euler: time step must be positive, got {h}")
    if not (np.isfinite(t_end) and t_end > t0):
        raise ModelError(f"implicit Euler: t_end must be after t0 = {t0}, got {t_end}")
    n = system.n_dof
    mass = lumped_mass(system.structure) if mass is None else np.asarray(mass, dtype=float)
    if mass.shape != (n,) or np.any(mass < 0) or not np.all(np.isfinite(mass)):
        raise ModelError(f"implicit Euler: mass must be {n} finite non-negative values")
    damping = np.asarray(damping, dtype=float)
    C = damping * mass if damping.ndim == 0 else damping
    if C.shape != (n,) or np.any(C < 0) or not np.all(np.isfinite(C)):
        raise ModelError(f"implicit Euler: damping must be a non-negative coefficient or {n} values")
    lam_f, mu_f = _as_function(lam), _as_function(mu)
    stepper = _Stepper(system, mass, C, lam_f, mu_f, paths, rtol, atol, max_newton, linear_solver)
    min_step = h / 1024.0 if min_step is None else float(min_step)

    q = stepper.supports(system.state(base=q0), t0)
    v = np.zeros(n) if v0 is None else np.array(v0, dtype=float)
    t = t0
    res = DynamicResult(q=q, v=v, t=t, success=False, message="")
    times, kinetic, resid = [], [], []
    dt = h
    free = system.free
    while t_end - t > 1e-9 * h:
        # the last step takes the remainder, never a sliver of a step after it (a step of
        # 1e-14 s makes the inertia terms M / dt^2 large enough to drown every force)
        dt = t_end - t if t_end - t <= dt * (1.0 + 1e-6) else dt
        q_new, r, its = stepper.step(q, v, t + dt, dt)
        if q_new is None:
            res.rejected_steps += 1
            dt *= 0.5
            if dt < min_step:
                res.q, res.v, res.t = q, v, t
                res.message = f"time step fell below {min_step:.3g} s at t = {t:.6g} s: {r}"
                break
            continue
        v = (q_new - q) / dt
        q = q_new
        t += dt
        system.accept(q)
        res.steps += 1
        res.newton_iterations.append(its)
        static = float(np.linalg.norm(r[free]))
        times.append(t)
        kinetic.append(0.5 * float(v @ (mass * v)))
        resid.append(static)
        if save_every and res.steps % save_every == 0:
            res.states.append((t, q.copy()))
        if callback is not None:
            callback(t, q, v)
        if stop is not None and stop(t, q, v, static):
            res.q, res.v, res.t = q, v, t
            res.success = True
            res.message = f"stopped at t = {t:.6g} s after {res.steps} steps"
            break
        dt = min(h, 2.0 * dt)
    else:
        res.q, res.v, res.t = q, v, t
        res.success = True
        res.message = f"reached t = {t:.6g} s in {res.steps} steps"
    res.times = np.array(times)
    res.kinetic_energy = np.array(kinetic)
    res.residual_norms = np.array(resid)
    res.wall_time_s = time.perf_counter() - start
    return res


def relax_to_rest(
    system,
    h: float,
    damping: float,
    t_max: float,
    q0: np.ndarray | None = None,
    mass: np.ndarray | None = None,
    lam=1.0,
    mu=0.0,
    paths: Sequence = (),
    force_tol: float = 1e-8,
    velocity_tol: float | None = None,
    **kw,
) -> DynamicResult:
    """Dynamic relaxation: damped implicit Euler until the structure is at rest in equilibrium.

    Stops (success) when the static residual at the free DOFs is below
    ``force_tol`` times the external force (or the reaction force, whichever
    is larger) and the largest velocity is below ``velocity_tol`` (default:
    ``force_tol`` times the model size per unit time); fails if ``t_max``
    passes first. Loads and supports are held at their values at ``t_max``
    when ``lam``/``mu`` are constants.
    """
    size = max(float(np.linalg.norm(np.ptp(system.structure.nodes, axis=0))), 1e-12)
    vtol = force_tol * size if velocity_tol is None else velocity_tol
    lam_f = _as_function(lam)

    def stop(t, q, v, static):
        scale = max(float(np.linalg.norm(system.external_force(lam_f(t)))),
                    float(np.linalg.norm(system.residual(q, lam_f(t))[system.constrained])), 1e-300)
        return static <= force_tol * scale and float(np.abs(v).max()) <= vtol

    res = implicit_euler(
        system, h, t_max, q0=q0, mass=mass, damping=damping, lam=lam, mu=mu, paths=paths, stop=stop, **kw
    )
    if res.success and res.t >= t_max - 1e-12 * h and not stop(res.t, res.q, res.v, res.residual_norm):
        res.success = False
        res.message = (
            f"not at rest by t = {t_max:.6g} s: static residual {res.residual_norm:.3e}, "
            f"largest velocity {float(np.abs(res.v).max()):.3e}"
        )
    return res
