"""Through a snap: the stable state beyond a critical point, and where a branch loses stability.

The critical state is pushed along its critical mode and carried downhill by
damped implicit Euler dynamics (the gridshell paper's own integrator) or an
energy descent, then Newton polishes it; a state that ends on a saddle is
pushed along its unstable mode and tried again. Where a stable branch loses
stability while the apex displacement still increases (a bifurcation), the
point is located by bisection on the displacement.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..solvers.cholesky import CholeskyFactor
from ..solvers.linear import SingularMatrixError
from ..solvers.newton import solve_static
from ..solvers.stability import count_negative, smallest_eigenpair

#: Newton solves use the LDL^T factorisation only: a solve that fails its
#: accuracy check (a tangent next to a critical point) is then retried with a
#: regularising shift, which is cheap, instead of a sparse LU factorisation,
#: which costs twenty LDL^T factorisations on these networks
LINEAR_SOLVER = "ldl"


#: Newton iterations of a bisection point's plain solve before the regularised one takes
#: over: from the middle of a bracket Newton converges in two or three, and next to the
#: critical point, where it overshoots, thirty iterations only wander
LOCATE_NEWTON = 8


def negative_count(setup, K) -> int:
    """Negative eigenvalues of the tangent ``K``: none where its Cholesky factorisation succeeds.

    Most points of a path are stable, and a supernodal Cholesky factorisation
    proves it at a fraction of the cost of the LDL^T whose pivot signs give
    the count (:func:`~shellform.solvers.stability.count_negative`, used
    where Cholesky fails): 0.45 s against 2.8-6 s at n = 39. The analysis is
    kept on ``setup`` for the next tangent.
    """
    try:
        F = CholeskyFactor(K, previous=getattr(setup, "_definite_factor", None), stored=True)
    except SingularMatrixError:
        return count_negative(K)
    setup._definite_factor = F
    return 0


def lowest_mode(K) -> np.ndarray | None:
    """Unit eigenvector of the smallest eigenvalue of ``K`` (None when it cannot be computed)."""
    return smallest_eigenpair(K)[1]


def dynamic_step_out(setup, q: np.ndarray, mu: float, h: float, damping: float, t_max: float,
                     first_step: float | None = None, hold_after_reject: int = 0, max_newton: int = 25):
    """Let the structure move from ``q`` under damped implicit Euler dynamics until it is nearly at rest.

    This is the paper's own way through a snap (inertia and damping carry the
    structure to the next stable state). ``first_step``,
    ``hold_after_reject`` and ``max_newton`` are those of
    :class:`~shellform.solvers.implicit_euler.ImplicitEulerOptions`. Returns
    the last state, or ``q`` when no time integrator is available.
    """
    try:
        from ..solvers.implicit_euler import implicit_euler, lumped_mass
    except ImportError:  # pragma: no cover - the integrator is optional here
        return q, 0
    system = setup.system
    mass = lumped_mass(system.structure, setup.model.network)
    scale = max(float(np.linalg.norm(system.residual(system.state(mu=mu, base=q))[system.constrained])), 1e-300)

    def stop(t, qq, v, static):
        return static <= 1e-7 * scale

    res = implicit_euler(system, h, t_max, q0=q, mass=mass, damping=damping, mu=mu, stop=stop,
                         linear_solver=LINEAR_SOLVER, first_step=first_step, hold_after_reject=hold_after_reject,
                         max_newton=max_newton)
    return res.q, int(sum(res.newton_iterations))


@dataclass(frozen=True)
class SettleOptions:
    """How :func:`settle` leaves a critical state and finds the stable one beyond it.

    Attributes
    ----------
    amplitude : float
        Size of each push along the critical (or unstable) mode: largest node
        displacement, relative to ``R``.
    method : {"dynamic", "energy", "auto"}
        Damped implicit Euler dynamics then Newton, a pure energy descent
        (Newton with regularised steps), or the descent first and the
        dynamics when it stalls.
    max_tries : int
        Pushes in all (a state that ends on a saddle is pushed again).
    rounds, iterations_per_round : int
        The energy descent runs in rounds of at most this many Newton
        iterations, the rod frames following the state in between.
    time_step, damping, t_max : float
        Time step [s], mass-proportional damping [1/s] and longest time [s]
        of the dynamics.
    first_step : float
        The dynamics start with this fraction of ``time_step`` and double it
        step by step: a structure pushed off a critical state is far from
        equilibrium, and full steps from rest there fail their Newton
        iterations (25 each, every one a factorisation) before a halved one
        succeeds.
    hold_after_reject : int
        Accepted steps at a reduced size, after a failed one, before the
        step grows again (a size that has just failed fails again).
    max_newton : int
        Newton iterations of one time step before it is rejected and
        halved. The mass of a gridshell is small against its stiffness at
        these time steps, so a step through a snap is nearly an energy
        descent of its own, and takes up to 48 iterations (n = 5 to 11,
        modes I and II) while still descending. Capped at 25, 2 to 7 steps
        per curve were rejected with their work done, 20 to 60 % more
        factorisations were needed, and the halved steps discretised the
        snap differently: a later threshold moved by up to 2e-3 R, and at
        n = 9 in mode II an extra snap appeared
        (``benchmarks/bench_hemisphere.py --snap-newton``).
    """

    amplitude: float
    method: str = "dynamic"
    max_tries: int = 4
    rounds: int = 10
    iterations_per_round: int = 40
    time_step: float = 1.0e-3
    damping: float = 100.0
    t_max: float = 0.5
    first_step: float = 0.125
    hold_after_reject: int = 3
    max_newton: int = 60


def settle(setup, q0: np.ndarray, mu: float, mode_free: np.ndarray | None, options: SettleOptions):
    """A stable equilibrium at ``mu`` reached from the critical state ``q0``.

    The start is pushed along ``mode_free`` (the critical mode) so that it
    leaves the unstable state; then damped dynamics or an energy descent
    (``options.method``) carries it downhill, and Newton polishes the result.
    When it ends on a saddle, it is pushed along the saddle's unstable mode
    and tried again. Returns ``(q, iterations, why)``, ``q`` None when no
    stable state was found.
    """
    o = options
    system = setup.system
    free = system.free
    n_x = 3 * setup.model.structure.n_nodes
    q = np.array(q0, dtype=float)
    iterations = 0
    for _ in range(o.max_tries):
        if mode_free is not None:
            d = np.zeros(system.n_dof)
            d[free] = mode_free
            trans = np.abs(d[:n_x]).max()
            if trans > 0:
                q = q + o.amplitude * setup.model.radius * d / trans
        if o.method == "auto":
            # a plain energy descent first; damped dynamics only when it stalls
            frames = setup.model.network.frames.state()
            res = solve_static(system, q, mu=mu, merit="energy", max_iter=30, rtol=1e-9)
            iterations += res.iterations
            if res.success and negative_count(setup, system.tangent_free(res.q)) == 0:
                system.accept(res.q)
                return res.q, iterations, "stable"
            setup.model.network.frames.restore(frames)
            q, its = dynamic_step_out(setup, q, mu, o.time_step, o.damping, o.t_max,
                                      o.first_step * o.time_step, o.hold_after_reject, o.max_newton)
            iterations += its
        elif o.method == "dynamic":
            q, its = dynamic_step_out(setup, q, mu, o.time_step, o.damping, o.t_max,
                                      o.first_step * o.time_step, o.hold_after_reject, o.max_newton)
            iterations += its
        # descend in rounds, accepting the state in between: a snap can turn rod
        # edges far from the stored frames, and the frames must follow
        for _ in range(o.rounds):
            # LU fallback here: next to a supercritical bifurcation the stable
            # state has a nearly singular tangent and shifted steps crawl
            res = solve_static(system, q, mu=mu, merit="energy", max_iter=o.iterations_per_round, rtol=1e-9)
            iterations += res.iterations
            q = res.q
            system.accept(q)
            if res.success:
                break
        else:
            return None, iterations, f"energy descent failed: {res.message}"
        K = system.tangent_free(q)
        n_neg = negative_count(setup, K)
        if n_neg == 0:
            return q, iterations, "stable"
        mode_free = lowest_mode(K)
        if mode_free is None:
            return None, iterations, "could not compute the unstable mode of a saddle"
    return None, iterations, f"still unstable after {o.max_tries} pushes"


def locate_stability_loss(setup, qa, mua, qb, mub, tol):
    """Locate where the path between a stable point A and an unstable point B loses stability.

    ``mu`` increases from A to B (no fold in between). Bisection on ``mu``
    with the stability of each point from the inertia of its tangent (the
    eigenvalue that crosses zero need not be the smallest one at A: soft
    twisting modes of the rods can lie below it), each point solved by
    Newton from the interpolated state. Returns ``(mu, q, located)``: the
    middle of the final bracket, the state at its unstable end, and whether
    the bracket came down to ``tol``.
    """
    system = setup.system
    lo, hi = (mua, qa), (mub, qb)
    while hi[0] - lo[0] > tol:
        mu = 0.5 * (lo[0] + hi[0])
        start = 0.5 * (lo[1] + hi[1])
        res = solve_static(system, start, mu=mu, merit="residual", max_iter=LOCATE_NEWTON,
                           linear_solver=LINEAR_SOLVER)
        if not res.success:
            # next to the critical point the tangent is nearly singular and the
            # plain Newton step overshoots; a regularised step does not
            res = solve_static(system, start, mu=mu, merit="energy", max_iter=30, linear_solver=LINEAR_SOLVER)
        if not res.success:
            return 0.5 * (lo[0] + hi[0]), hi[1], False
        if negative_count(setup, system.tangent_free(res.q)) == 0:
            lo = (mu, res.q)
        else:
            hi = (mu, res.q)
    return 0.5 * (lo[0] + hi[0]), hi[1], True
