"""One implicit Euler step: Newton on the incremental potential of the free DOFs (Eq. 2 of the gridshell paper).

The step minimises ``Phi(dq) = |dq - h v_k|_M^2 / (2 h^2) + |dq|_C^2 / (2 h) + Pi(q_k + dq, lam)``
(:mod:`shellform.solvers.implicit_euler`): chord iterations on the kept factor
of the last Jacobian while they divide the residual fast enough, Newton with a
line search on ``Phi`` otherwise, a diagonal shift where the Jacobian is not
positive definite.

"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from .equilibrium import EquilibriumCheck, forces_in_play, roundoff_level
from .linear import SingularMatrixError, factorize, shift_diagonal

#: A chord iteration with a kept factor must divide the step's residual by 1 / CHORD_RATE, or
#: Newton takes over (``benchmarks/bench_hemisphere.py --chord-rates``).
CHORD_RATE = 0.1


def as_function(value) -> Callable[[float], float]:
    if callable(value):
        return value
    v = float(value)
    return lambda t: v


def _max_abs(v: np.ndarray) -> float:
    return float(np.max(np.abs(v), initial=0.0))


class Stepper:
    """One implicit Euler step: Newton on the incremental potential of the free DOFs.

    ``options`` is the run's :class:`~shellform.solvers.implicit_euler.ImplicitEulerOptions`.
    """

    def __init__(self, system, options, mass: np.ndarray, damping: np.ndarray):
        self.system = system
        self.o = options
        self.mass, self.damping = mass, damping
        self.lam, self.mu = as_function(options.lam), as_function(options.mu)
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
            diagonal = J.diagonal()
            eq = pb.test(q, r, R, diagonal)
            if eq.converged:
                return q, r, it - 1
            if eq.near_roundoff and it > 1 and norm > 0.1 * previous:
                return _stalled(eq, q, r, it - 1)
            taken = self._descend(pb, q, R, J, diagonal, norm, phi)
            if eq.near_roundoff and (taken is None or not taken[3] < norm):
                return _stalled(eq, q, r, it - 1)
            if taken is None:
                return None, f"Newton iteration {it}: no step decreased the incremental potential", it
            previous = norm
            q, r, R, norm, phi = taken
        eq = pb.test(q, r, R, pb.jacobian(q).diagonal())
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

    def _descend(self, pb, q, R, J, diagonal, norm, phi0=None):
        """The Newton step from ``q`` (``J`` the Jacobian there, ``diagonal`` its diagonal, ``phi0`` the
        incremental potential if known: that of the point the last step reached), shifted until it lowers
        the incremental potential: ``(q, r, R, |R|, phi)`` after it, or None when no shift gives one."""
        if phi0 is None:
            phi0 = pb.merit(q)
        diag = np.abs(diagonal)
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

    def __init__(self, stepper: Stepper, q_k, v_k, t_next, h):
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

    def test(self, q, r, R, diagonal) -> EquilibriumCheck:
        """The equilibrium test of ``R`` (``diagonal`` that of the Jacobian at ``q``, for the round-off level)."""
        reactions = r[self.system.constrained]
        scale = max(self.in_play[0], float(np.linalg.norm(reactions)))
        scale_max = max(self.in_play[1], _max_abs(reactions))
        return EquilibriumCheck(float(np.linalg.norm(R)), scale, self.o.rtol * scale + self.o.atol,
                                roundoff_level(diagonal, q), self.o.roundoff_rtol, self.applied,
                                _max_abs(R), scale_max)

    def backtrack(self, q, p, phi0, slope, norm):
        """Halve the step ``p`` from ``q`` until the potential falls enough: ``(q, r, R, |R|, Phi)``, or None."""
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
                    return q_try, r_try, R_try, n_try, phi
                # at round-off level Phi cannot rank steps; the residual still can
                if abs(phi - phi0) <= 1e3 * eps * (abs(phi0) + abs(slope)) and n_try < norm:
                    return q_try, r_try, R_try, n_try, phi
            alpha *= 0.5
        return None
