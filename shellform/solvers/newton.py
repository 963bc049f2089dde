"""Static equilibrium by Newton's method with a backtracking line search."""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from .linear import SingularMatrixError, factorize


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


def solve_static(
    system,
    q0: np.ndarray | None = None,
    lam: float = 1.0,
    mu: float = 0.0,
    rtol: float = 1e-10,
    atol: float = 1e-12,
    max_iter: int = 100,
    merit: str = "energy",
    linear_solver: str = "direct",
    max_backtracks: int = 30,
    callback=None,
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
    rtol, atol : float
        Converged when ``|r_free| <= rtol * scale + atol``, with ``scale`` the
        larger of the external-force norm and the reaction norm, or when the
        residual reaches the round-off floor of the tangent (reported in the
        message), below which no iteration can go.
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
    callback : callable, optional
        Called as ``callback(iteration, residual_norm)`` after every accepted
        step (progress display).

    Returns
    -------
    StaticResult
    """
    t0 = time.perf_counter()
    if merit not in ("residual", "energy"):
        raise ValueError(f"merit must be 'residual' or 'energy', got {merit!r}")
    q = system.state(mu=mu, base=q0)
    if not np.all(np.isfinite(q)):
        bad = int(np.flatnonzero(~np.isfinite(q))[0])
        raise ValueError(f"starting state has a non-finite value at DOF {bad} (node {bad // 3})")
    free = system.free

    def evaluate(qq):
        r = system.residual(qq, lam)
        return r, float(np.linalg.norm(r[free]))

    ext = system.external_force(lam)
    size = max(float(np.linalg.norm(np.ptp(system.structure.nodes, axis=0))), 1e-12)
    r, norm = evaluate(q)
    norms = [norm]
    n_reg = 0

    def tolerance(rr, K=None):
        scale = max(float(np.linalg.norm(ext)), float(np.linalg.norm(rr[system.constrained])))
        tol_ = rtol * scale + atol
        if K is not None:
            # round-off floor: a residual entry sums member forces of size
            # stiffness x coordinate, each known to machine precision only;
            # asking for less than this would never terminate on stiff members
            floor = 10.0 * np.finfo(float).eps * np.linalg.norm(K.diagonal()) * float(np.abs(q).max())
            tol_ = max(tol_, floor)
        return tol_

    def result(success, message, it):
        return StaticResult(
            q=q, success=success, message=message, iterations=it, residual_norms=norms,
            tolerance=tol, lam=lam, mu=mu, reactions=system.reactions(q, lam),
            regularised_steps=n_reg, wall_time_s=time.perf_counter() - t0,
        )

    tol = tolerance(r)
    if not np.isfinite(norm):
        return result(False, "residual is not finite at the starting state", 0)

    def converged_message():
        kind = "converged" if norm <= tolerance(r) else "converged to the round-off floor"
        return f"{kind}: |r| = {norm:.3e} <= {tol:.3e}"

    for it in range(1, max_iter + 1):
        if norm <= tol:
            return result(True, converged_message(), it - 1)
        K = system.tangent_free(q)
        tol = tolerance(r, K)
        if norm <= tol:
            return result(True, converged_message(), it - 1)
        rf = r[free]
        phi0 = system.energy(q, lam) if merit == "energy" else 0.5 * norm**2
        accepted = False
        singular = True
        for shift in _shift_sequence(K, norm, size):
            try:
                A = K if shift == 0.0 else K + sp.diags(np.full(K.shape[0], shift))
                p = factorize(A, linear_solver).solve(-rf)
            except SingularMatrixError:
                continue
            singular = False
            slope = float(rf @ p) if merit == "energy" else -2.0 * phi0
            if slope >= 0.0:
                continue  # not a descent direction of the energy: shift further
            q_try, r_try, norm_try = _line_search(system, q, p, lam, merit, phi0, slope, norm, evaluate, max_backtracks)
            if q_try is not None:
                accepted = True
                n_reg += int(shift > 0.0)
                break
        if not accepted:
            why = "the tangent is singular even with a large diagonal shift" if singular else (
                f"no step decreased the {merit} merit, even with a large diagonal shift")
            return result(False, f"iteration {it}: {why}; the structure may be a mechanism at this state", it - 1)
        q, r, norm = q_try, r_try, norm_try
        norms.append(norm)
        if callback is not None:
            callback(it, norm)
        tol = max(tol, tolerance(r))
    if norm <= tol:
        return result(True, converged_message(), max_iter)
    return result(False, f"not converged in {max_iter} iterations: |r| = {norm:.3e} > tolerance {tol:.3e}", max_iter)


def _line_search(system, q, p, lam, merit, phi0, slope, norm, evaluate, max_backtracks):
    """Backtracking (Armijo) along ``p``; returns (q, r, |r|) or (None, None, None)."""
    free = system.free
    alpha = 1.0
    eps = np.finfo(float).eps
    for _ in range(max_backtracks):
        q_try = q.copy()
        q_try[free] += alpha * p
        r_try, norm_try = evaluate(q_try)
        if np.isfinite(norm_try):
            phi = system.energy(q_try, lam) if merit == "energy" else 0.5 * norm_try**2
            if np.isfinite(phi) and phi <= phi0 + 1e-4 * alpha * slope:
                return q_try, r_try, norm_try
            # close to a minimum the energy changes less than its round-off and
            # cannot rank steps; the residual norm still can
            flat = merit == "energy" and abs(phi - phi0) <= 1e3 * eps * (abs(phi0) + abs(slope))
            if flat and norm_try < (1.0 - 1e-4 * alpha) * norm:
                return q_try, r_try, norm_try
        alpha *= 0.5
    return None, None, None
