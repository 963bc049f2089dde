"""Dynamic relaxation of hanging rope nets: the multi-body rope approach (MRA).

Every node of the net is a mass; the ropes between the nodes pull only when
taut. The net falls from its start configuration under its weight and comes to
rest in the hanging (funicular) shape. At every free DOF the d'Alembert
balance of Eqs. (6)-(8) of the MRA paper reads

    m_i a_i + c_i v_i = -r_i(q),        r = f_int(q) - f_ext  (System.residual)

with lumped nodal masses ``m_i`` (``Structure.nodal_mass()`` plus optional
extra inertia) and viscous damping ``c_i = damping * m_i``. Rest is reached
when every nodal velocity and every nodal acceleration is below a tolerance.

Three schemes reach that rest state; ``scheme`` selects one:

``"rk4"``
    The paper's scheme: explicit classical Runge-Kutta time stepping of the
    damped motion with a fixed step below the stability limit (from a
    Gershgorin bound of the rope stiffnesses over the masses).
``"kinetic"``
    Explicit leapfrog with kinetic damping (Cundall/Barnes): no viscosity;
    whenever the kinetic energy passes a peak the velocities are zeroed and
    the state moved back to the peak. One force evaluation per step instead of
    four, and no viscous drag slowing the fall.
``"implicit"``
    Pseudo-transient continuation: each step is a backward-Euler step of the
    motion from rest, ``(K + (1/dt^2 + c/dt) M) dq = -r``, with the global sparse
    tangent ``System.tangent_free``. The total potential of a hanging net is
    convex (a taut rope's energy is a convex function of the node positions,
    a slack one is zero, the weight is linear), so a step is accepted when the
    potential falls as the quadratic model predicts, and the pseudo time step
    grows; when it grows without bound the step is Newton's method and
    convergence is quadratic. The mass term keeps the matrix positive definite
    while ropes are slack (a slack rope has no stiffness). Five devices make
    it fast on nets of nearly inextensible ropes: a start from the
    force-density shape (one scalar linear solve, :func:`force_density_start`)
    instead of the flat planform, so the net does not have to fall into its
    shape; a continuation in the rope stiffness (soft ropes first, ten times
    stiffer per stage, the true EA last); a line search on the potential
    along each step (its changes summed member by member, so they stay
    accurate near equilibrium); conjugate gradients preconditioned by the
    factor of an earlier step, refactorising only when they stall (CHOLMOD's
    supernodal Cholesky; LDL^T or SuperLU in nested-dissection order on
    request); and, once only a few nodes along the fronts between taut and
    slack regions are far from balance, Newton steps on the patches around
    them with the rest of the net held (:func:`_sweep_fronts`). A step's
    slack ropes enter its model by an active set (:func:`_engage_slack_ropes`),
    settled on the patches where its rounds leave ropes in the wrong state
    (:func:`_settle_slack_set`).

All three stop on the same test (nodal velocity and acceleration below the
tolerances) and reach the same equilibrium: the minimum of the potential.
"""

from __future__ import annotations

import copy
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from ..effects.axial import two_node_blocks
from ..effects.base import scatter
from ..errors import ModelError
from .linear import CholeskyFactor, SingularMatrixError, factorize
from .local_correction import LocalCorrection
from .patch import NodeGraph, Patch, patchable

SCHEMES = ("rk4", "kinetic", "implicit")
START_STATES = ("auto", "reference", "force_density")

#: stability limit of classical RK4 on the imaginary axis is 2*sqrt(2); of leapfrog, 2
_RK4_LIMIT = 2.8
_LEAPFROG_LIMIT = 2.0


@dataclass
class RelaxationProgress:
    """What a progress callback receives.

    ``q`` and ``v`` are the current state (all DOFs, copies the callback may
    keep): saving ``q`` is a checkpoint. The equilibrium is the minimum of a
    convex potential, so ``relax(system, q0=saved_q)`` (for the explicit
    schemes also ``v0=saved_v`` to continue the same trajectory) reaches the
    same shape as an uninterrupted run. For the implicit scheme ``v`` is the
    last pseudo step over its pseudo time step, and a restart ignores it.
    """

    scheme: str
    iteration: int
    time: float
    max_velocity: float
    max_acceleration: float
    residual_norm: float
    wall_time_s: float
    q: np.ndarray | None = None
    v: np.ndarray | None = None


@dataclass
class RelaxationResult:
    """Outcome of a relaxation.

    Attributes
    ----------
    q : ndarray
        Final DOF vector (the last finite state when the run failed).
    v : ndarray
        Final velocity of every DOF (zero at constrained DOFs).
    success : bool
        Every nodal velocity and acceleration met its tolerance.
    message : str
        What happened, in words.
    scheme : str
        ``"rk4"``, ``"kinetic"`` or ``"implicit"``.
    iterations : int
        Time steps (explicit schemes) or accepted pseudo-time steps (implicit).
    max_velocity, max_acceleration : float
        Largest nodal speed [m/s] and nodal acceleration magnitude [m/s^2] at
        the final state; the acceleration is the out-of-balance force over the
        physical mass, ``|r_i| / m_i``, except for ``"rk4"``, which reports the
        acceleration of its equation of motion, ``|r_i + c_i v_i| / m_i``
        (the same at rest).
    residual_norm : float
        Euclidean norm of the out-of-balance force at the free DOFs [N].
    velocity_tol, acceleration_tol : float
        The tolerances used.
    time : float
        Simulated time (explicit schemes) or accumulated pseudo time.
    time_step : float
        Time step of the explicit schemes; last pseudo time step (implicit).
    wall_time_s : float
    reactions : ndarray
        Support reactions at every DOF (zero where free) at the final state.
    residual_evaluations, factorizations, rejected_steps, linear_iterations : int
        Work counters (``linear_iterations``: preconditioned CG iterations of
        the implicit scheme).
    local_steps : int
        Newton steps of the implicit scheme on patches around the nodes that
        were furthest from balance, the rest of the net held
        (:func:`_sweep_fronts`); not counted in ``iterations`` or
        ``factorizations``.
    corrected_solves : int
        Solves of the implicit scheme by CG with the kept factor corrected on
        the nodes whose tangent entries had changed (:class:`_SPDSolve`).
    repaired_steps : int
        Steps of the implicit scheme kept at full length with the patch
        around the few ropes that made them overshoot relaxed from there
        (:func:`_repair_full_step`); counted in ``iterations``.
    history : dict of lists
        ``iteration``, ``max_velocity``, ``max_acceleration``,
        ``residual_norm`` sampled every ``progress_every`` iterations.
    start : str
        ``"given"`` (``q0`` was passed), ``"reference"`` or ``"force_density"``;
        :func:`~shellform.mra.form_find` reports ``"coarse_net"`` for its start
        from a coarser net (whose relaxation time is then in ``wall_time_s``).
    """

    q: np.ndarray
    v: np.ndarray
    success: bool
    message: str
    scheme: str
    iterations: int
    max_velocity: float
    max_acceleration: float
    residual_norm: float
    velocity_tol: float
    acceleration_tol: float
    time: float
    time_step: float
    wall_time_s: float
    reactions: np.ndarray
    residual_evaluations: int = 0
    factorizations: int = 0
    rejected_steps: int = 0
    linear_iterations: int = 0
    local_steps: int = 0
    corrected_solves: int = 0
    repaired_steps: int = 0
    history: dict = field(default_factory=dict)
    start: str = "reference"


# ---------------------------------------------------------------------------
# masses, scales and bounds
# ---------------------------------------------------------------------------
def nodal_masses(system, extra_mass=None) -> np.ndarray:
    """Lumped nodal masses [kg]: the structure's masses plus ``extra_mass``.

    ``extra_mass`` (scalar or one value per node) adds inertia only; the
    weight is what the System's gravity effect was built with.
    """
    s = system.structure
    m = s.nodal_mass().astype(float)
    if extra_mass is not None:
        extra = np.broadcast_to(np.asarray(extra_mass, dtype=float), m.shape)
        if not np.all(np.isfinite(extra)) or np.any(extra < 0):
            raise ModelError("relaxation: extra_mass must be finite and non-negative")
        m = m + extra
    return m


def _free_node_mask(system) -> np.ndarray:
    n = system.structure.n_nodes
    free = np.zeros(3 * n, dtype=bool)
    free[system.free] = True
    return free.reshape(n, 3).any(axis=1)


def node_stiffness_bound(system, q: np.ndarray) -> np.ndarray:
    """Upper bound, per node, of the row sums of the tangent's 3x3 block norms.

    For an axial member the tangent block has norm ``max(EA/L, |N|/l)``, which
    is ``EA/L`` whenever the member is not compressed below half its rest
    length; the bound therefore holds for every state a rope net passes
    through, taut or slack. Other effects contribute the absolute row sums
    of their Hessian at ``q`` (a state-dependent estimate).
    By the block Gershgorin theorem, ``lambda_max(M^-1 K) <= max_i S_i / m_i``.
    """
    n = system.structure.n_nodes
    S = np.zeros(n)
    for e in system.effects:
        if all(hasattr(e, a) for a in ("conn", "EA", "L")):
            _, length = e._geometry(q)
            k = (e.EA / e.L) * np.maximum(1.0, (e.L - length) / np.maximum(length, 1e-300))
            S += 2.0 * (np.bincount(e.conn[:, 0], k, minlength=n) + np.bincount(e.conn[:, 1], k, minlength=n))
        else:
            rows, _ = e.hessian_pattern()
            if len(rows) == 0:
                continue
            row_sum = np.bincount(rows, np.abs(e.hessian_values(q)), minlength=system.n_dof)
            S += 2.0 * row_sum[: 3 * n].reshape(n, 3).max(axis=1)
    return S


def _nodal_norms(system, x_free: np.ndarray) -> np.ndarray:
    """Euclidean norm at every node of a free-DOF vector (zero at held nodes)."""
    full = np.zeros(system.n_dof)
    full[system.free] = x_free
    full = full.reshape(-1, 3)
    return np.sqrt(np.einsum("ij,ij->i", full, full))


def _nodal_max(system, x_free: np.ndarray) -> float:
    """Largest Euclidean norm over nodes of a free-DOF vector."""
    return float(_nodal_norms(system, x_free).max())


@dataclass
class _Setup:
    q: np.ndarray
    m_node: np.ndarray
    m: np.ndarray  # per free DOF
    g_ref: float
    L_ref: float
    v_tol: float
    a_tol: float
    damping: float
    a_tol_asked: float
    v0: np.ndarray  # start velocity at the free DOFs
    start: str = "reference"


def _start_velocity(system, v0) -> np.ndarray:
    """Start velocity at the free DOFs (zero by default), checked."""
    if v0 is None:
        return np.zeros(system.free.size)
    v0 = np.asarray(v0, dtype=float)
    if v0.shape != (system.n_dof,):
        raise ModelError(f"relaxation: v0 must have one value per DOF ({system.n_dof}), got shape {v0.shape}")
    if not np.all(np.isfinite(v0)):
        bad = int(np.flatnonzero(~np.isfinite(v0))[0])
        raise ModelError(f"relaxation: the start velocity has a non-finite value at DOF {bad} (node {bad // 3})")
    return v0[system.free].copy()


def _setup(system, q0, lam, mu, extra_mass, rtol, v_tol, a_tol, damping, v0=None) -> _Setup:
    s = system.structure
    if system.n_dof != 3 * s.n_nodes:
        raise ModelError(
            f"relaxation: the structure has {s.n_twist} twist DOFs; the rope-net relaxation "
            "handles translations only"
        )
    q = system.state(mu=mu, base=q0)
    if not np.all(np.isfinite(q)):
        bad = int(np.flatnonzero(~np.isfinite(q))[0])
        raise ModelError(f"relaxation: the start state has a non-finite value at DOF {bad} (node {bad // 3})")
    m_node = nodal_masses(system, extra_mass)
    zero = np.flatnonzero(_free_node_mask(system) & (m_node <= 0))
    if zero.size:
        raise ModelError(
            f"relaxation: free node {int(zero[0])} has no mass ({zero.size} such nodes); every free node of a "
            "hanging net must be a mass: give the ropes a mass per length, add point masses, or pass extra_mass"
        )
    m = np.repeat(m_node, 3)[system.free]
    f = system.external_force(lam).reshape(-1, 3)
    fn = np.linalg.norm(f, axis=1)
    loaded = fn > 0
    g_ref = float(np.max(fn[loaded] / m_node[loaded])) if np.any(loaded & (m_node > 0)) else 9.81
    ext = np.ptp(q.reshape(-1, 3), axis=0)
    L_ref = float(ext.max()) if ext.max() > 0 else 1.0
    a_tol = rtol * g_ref if a_tol is None else float(a_tol)
    v_tol = rtol * np.sqrt(g_ref * L_ref) if v_tol is None else float(v_tol)
    if not (a_tol > 0 and v_tol > 0):
        raise ModelError(f"relaxation: tolerances must be positive, got velocity {v_tol}, acceleration {a_tol}")
    # Forces of very stiff ropes carry a round-off error of about eps * (EA/L) * |x|;
    # an acceleration tolerance below that level can never be met.
    S = node_stiffness_bound(system, q)
    fn_mask = _free_node_mask(system)
    a_floor = 0.0
    if np.any(fn_mask):
        # a rope's extension l - L is computed from coordinates of size |x| (error
        # eps |x|); S_i sums 2 EA/L over the node's ropes
        x_max = max(float(np.max(np.abs(q))), L_ref)
        a_floor = float(0.5 * np.finfo(float).eps * x_max * np.max(S[fn_mask] / m_node[fn_mask]))
    a_tol_asked = a_tol
    a_tol = max(a_tol, a_floor)
    # critical damping of the slowest, pendulum-like mode of a net of size L_ref
    damping = 2.0 * np.sqrt(g_ref / L_ref) if damping is None else float(damping)
    if damping < 0 or not np.isfinite(damping):
        raise ModelError(f"relaxation: damping must be finite and non-negative, got {damping}")
    return _Setup(q, m_node, m, g_ref, L_ref, v_tol, a_tol, damping, a_tol_asked, _start_velocity(system, v0))


def stable_time_step(system, q=None, extra_mass=None, scheme: str = "rk4", damping: float = 0.0) -> float:
    """Explicit time step allowed by the stiffness bound, with a 10 % margin.

    ``omega_max^2 <= max_i S_i / m_i`` (:func:`node_stiffness_bound`); the step is
    ``0.9 * 2.8 / omega`` for RK4 (whose stability region reaches 2.83 on the
    imaginary axis, with ``omega`` raised to ``hypot(omega, damping)`` for the
    damped eigenvalues) and ``0.9 * 2 / omega`` for leapfrog.
    """
    q = system.q_ref if q is None else q
    return _bound_step(system, q, nodal_masses(system, extra_mass), scheme, damping)


def _bound_step(system, q, m_node, scheme, damping):
    S = node_stiffness_bound(system, q)
    free_nodes = _free_node_mask(system) & (S > 0)
    if not np.any(free_nodes):
        raise ModelError("relaxation: no free node is attached to a member; nothing holds the net")
    omega = float(np.sqrt(np.max(S[free_nodes] / np.maximum(m_node[free_nodes], 1e-300))))
    if scheme == "rk4":
        return 0.9 * _RK4_LIMIT / float(np.hypot(omega, damping))
    return 0.9 * _LEAPFROG_LIMIT / omega


# ---------------------------------------------------------------------------
# start state of the implicit scheme: the force-density shape
# ---------------------------------------------------------------------------
def _scalar_solver(A: sp.csr_matrix):
    """``solve(B)`` for a graph Laplacian with Dirichlet rows removed (SPD, one column per right-hand side)."""
    if A.shape[0] <= 100_000:
        import scipy.sparse.linalg as spla

        lu = spla.splu(sp.csc_matrix(A))
        return lu.solve
    import pyamg

    ml = pyamg.smoothed_aggregation_solver(sp.csr_matrix(A), symmetry="symmetric")

    def solve(B):
        cols = [ml.solve(B[:, k], tol=1e-12, accel="cg", maxiter=500) for k in range(B.shape[1])]
        return np.column_stack(cols)

    return solve


def force_density_start(system, lam: float = 1.0, stiffness_scale: float = 1.0, base=None) -> np.ndarray | None:
    """Start state from the force-density method: a hanging shape from one linear solve.

    With one force density ``c`` in every axial member, nodal equilibrium is
    ``c L_G x = f`` with ``L_G`` the graph Laplacian of the members (one scalar
    matrix shared by x, y and z), so the free coordinates are
    ``x = x_b + x_f / c``: the supports' harmonic extension plus the load's
    response. ``c`` is chosen so that the shape agrees with the members'
    stiffness on average: the mean strain ``l / L - 1`` equals the mean of
    ``c l / (s EA)``, the strain of members carrying the force-density
    tension ``c l`` at the stiffness ``s EA`` (``s = stiffness_scale``, the
    first stage of a stiffness continuation). Returns None when the members
    do not hold every free node (the Laplacian is singular) or the net has no
    load; the caller then starts from the reference state.
    """
    parts = _force_density_parts(system, None, lam, base)
    if parts is None:
        return None
    q, Xb, Xf, conn, L, EA = parts
    EA = stiffness_scale * EA
    f = system.external_force(lam)

    def lengths(cd):
        Y = Xb + Xf / cd
        return np.linalg.norm(Y[conn[:, 1]] - Y[conn[:, 0]], axis=1)

    def mismatch(log_c):
        cd = np.exp(log_c)
        ln = lengths(cd)
        return float(np.mean(ln / L - 1.0) - np.mean(cd * ln / EA))

    # mismatch > 0 for a small force density (deep shape), < 0 for a large one (flat shape, members
    # in compression or at their harmonic length); bracket the root on a log scale
    lo, hi = np.log(1e-12 * float(np.abs(f).max())), np.log(1e12 * float(np.abs(f).max()))
    f_lo, f_hi = mismatch(lo), mismatch(hi)
    if not (f_lo > 0 > f_hi):
        return None
    # Illinois regula falsi on the monotone mismatch (a few dozen length evaluations)
    side = 0
    for _ in range(100):
        mid = hi - f_hi * (hi - lo) / (f_hi - f_lo)
        f_mid = mismatch(mid)
        if f_mid > 0:
            lo, f_lo = mid, f_mid
            f_hi = 0.5 * f_hi if side == 1 else f_hi
            side = 1
        else:
            hi, f_hi = mid, f_mid
            f_lo = 0.5 * f_lo if side == -1 else f_lo
            side = -1
        if hi - lo < 1e-6:
            break
    cd = np.exp(0.5 * (lo + hi))
    out = q.copy()
    out[: Xb.size] = (Xb + Xf / cd).ravel()
    return out


def force_density_shape(system, density, lam: float = 1.0, base=None) -> np.ndarray | None:
    """The shape in which the axial members with force densities ``density`` balance the load.

    One weighted-Laplacian solve per group of coordinates held alike: with
    the force density ``q_e = N_e / l_e`` given for every member, nodal
    equilibrium is linear in the positions. ``density`` runs over the axial
    members in the order of the System's effects. Returns None where
    :func:`force_density_start` would (a free node not held by members with
    positive density, or no load).
    """
    density = np.asarray(density, dtype=float)
    n_members = sum(len(e.L) for e in _axial_effects(system))
    if density.shape != (n_members,) or not np.all(np.isfinite(density)) or np.any(density < 0):
        raise ModelError(f"force-density shape: expected {n_members} finite, non-negative force densities, "
                         f"got shape {density.shape}")
    parts = _force_density_parts(system, density, lam, base)
    if parts is None:
        return None
    q, Xb, Xf = parts[:3]
    out = q.copy()
    out[: Xb.size] = (Xb + Xf).ravel()
    return out


def _force_density_parts(system, weights, lam, base):
    """``(q, X_b, X_f, conn, L, EA)``: a weighted-Laplacian solve of the axial members.

    ``X_b`` is the supports' harmonic extension and ``X_f`` the load's response
    for member weights ``weights`` (all ones when None): the shape with force
    densities ``c * weights`` is ``X_b + X_f / c``.
    """
    axial = _axial_effects(system)
    if not axial or len(axial) != len([e for e in system.effects if not e.is_external]):
        return None
    n = system.structure.n_nodes
    conn = np.concatenate([e.conn for e in axial])
    L = np.concatenate([e.L for e in axial])
    EA = np.concatenate([np.broadcast_to(e.EA, e.L.shape) for e in axial])
    w = np.ones(len(conn)) if weights is None else weights
    f = system.external_force(lam).reshape(n, 3)
    q = (system.q_ref if base is None else np.asarray(base, dtype=float)).copy()
    X = q[: 3 * n].reshape(n, 3).copy()
    if not np.any(f):
        return None
    # a member of zero weight holds nothing: leave it out of the graph
    held = w > 0
    G = sp.coo_matrix((w[held], (conn[held, 0], conn[held, 1])), shape=(n, n))
    G = (G + G.T).tocsr()
    lap = (sp.diags(np.asarray(G.sum(axis=1)).ravel()) - G).tocsr()
    free = np.zeros(3 * n, dtype=bool)
    free[system.free] = True
    free = free.reshape(n, 3)
    Xb, Xf = X.copy(), np.zeros_like(X)
    ncomp, labels = connected_components(G, directed=False)
    patterns = {}
    for c in range(3):
        patterns.setdefault(free[:, c].tobytes(), []).append(c)
    for key, comps in patterns.items():
        fi = np.flatnonzero(free[:, comps[0]])
        ci = np.flatnonzero(~free[:, comps[0]])
        if fi.size == 0:
            continue
        A = lap[fi][:, fi]
        # a free node with no path to a constrained one makes A singular: no shape to start from
        connected = np.zeros(ncomp, dtype=bool)
        connected[labels[ci]] = True
        if ci.size == 0 or not np.all(connected[labels[fi]]):
            return None
        rhs_b = -(lap[fi][:, ci] @ X[np.ix_(ci, comps)])
        try:
            sol = _scalar_solver(A)(np.column_stack([rhs_b, f[np.ix_(fi, comps)]]))
        except RuntimeError:
            return None
        Xb[np.ix_(fi, comps)] = sol[:, : len(comps)]
        Xf[np.ix_(fi, comps)] = sol[:, len(comps):]
    if not (np.all(np.isfinite(Xb)) and np.all(np.isfinite(Xf))):
        return None
    return q, Xb, Xf, conn, L, EA


# ---------------------------------------------------------------------------
# linear solves for the implicit scheme
# ---------------------------------------------------------------------------
#: Refactorisation time over the time of one preconditioned CG iteration (a solve with the
#: factor and a product with the matrix) on net tangents of so many unknowns, measured in
#: ``benchmarks/results/bench_factorization.md``: ``(unknowns, ratio)`` points per method.
REFACTOR_COST = {
    "cholesky": ((28_812, 7.6), (295_788, 9.9), (2_988_012, 23.0)),
    "ldl": ((28_812, 22.0), (295_788, 104.0)),
}
#: the ratio assumed for the other methods
OTHER_REFACTOR_COST = 20.0


def iteration_budget(method: str, n: int) -> int:
    """CG iterations worth trying with a kept factor before refactorising a matrix of ``n`` unknowns.

    Half the cost of a refactorisation in iterations (:data:`REFACTOR_COST`,
    interpolated log-log between the measured sizes, constant below the
    smallest, growing as the last two above the largest), between 5 and 60:
    a failed attempt then costs at most half a factorisation. Measured
    sizes, not times of the run, set it, so that a relaxation takes the same
    path in every run.
    """
    points = REFACTOR_COST.get(method)
    if points is None:
        ratio = OTHER_REFACTOR_COST
    else:
        log_n, log_r = np.log(np.array(points, dtype=float)).T
        x = np.log(max(float(n), 1.0))
        if x > log_n[-1]:
            ratio = float(np.exp(log_r[-1] + (x - log_n[-1]) * (log_r[-1] - log_r[-2]) / (log_n[-1] - log_n[-2])))
        else:
            ratio = float(np.exp(np.interp(x, log_n, log_r)))
    return int(round(min(max(0.5 * ratio, 5), 60)))


class _SPDSolve:
    """Solves with ``A = K + sigma M`` (symmetric positive definite by construction).

    A factorisation is kept from step to step: the next system is first solved
    by conjugate gradients preconditioned with the old factor (a few cheap
    iterations while the tangent changes little), and refactorised only when
    that does not converge within ``cg_max`` iterations. By default
    ``cg_max`` is half as many iterations as one refactorisation costs in
    preconditioned iterations (between 5 and 60, :func:`iteration_budget`),
    so a failed attempt never costs more than half a factorisation. That
    cost follows the number of unknowns (ratios measured on net tangents),
    not the times of the run: with the run's times the budget, and with it
    the path of the relaxation, changed from run to run (19 to 23 steps on
    one 316 x 316 net, 37 to 50 on one 1000 x 1000 net).
    An attempt saves at least half a factorisation when it converges and
    loses about half of one when it does not, so it pays only while attempts
    converge more often than not. A running estimate of that rate (each
    attempt weighs 30 %) decides: below one half the old factor is not tried,
    except on every fourth solve, which keeps the estimate current. On a
    316 x 316 net 120 of 164 attempts failed, each after five iterations
    costing 0.35 s beside a 0.8 s factorisation.

    The old factor is corrected where the matrix has changed since it was
    made (``correct``, :class:`~shellform.solvers.local_correction.LocalCorrection`):
    ropes pulled taut or gone slack change their blocks by about their whole
    size, each such rope is an outlying eigenvalue for the old factor alone,
    and an exact solve on the nodes around them takes those out. When the
    changed nodes are too many (a new stiffness stage changes every entry)
    the matrix is factorised without an attempt.

    ``"cholesky"`` (what ``"auto"`` means) is CHOLMOD's supernodal Cholesky
    (:class:`~shellform.solvers.linear.CholeskyFactor`) with its analysis
    kept for the fixed pattern: ``K + sigma M`` is positive definite here, so
    no inertia and no pivoting are needed. On the taut tangent of a
    316 x 316 net one refactorisation took 0.63 s against QDLDL's 9.6 s
    (``benchmarks/results/bench_factorization.md``).

    ``"ldl"`` keeps one QDLDL object and refactorises numerically on the same
    pattern (the ordering and symbolic analysis are done once; QDLDL orders
    by approximate minimum degree). ``"nd"`` factorises with SuperLU in a
    nested-dissection order of the nodes computed once from their
    coordinates (:func:`nested_dissection`); on the surface-like graph of a
    net its fill grows like ``N log N`` instead of AMD's faster growth.
    Measured on one tangent of a 317 x 317 net (297,675 DOFs): QDLDL 10.9 s,
    SuperLU in nested-dissection order 5.2 s; at 101 x 101 (29,403 DOFs)
    0.14 s and 0.2 s. Explicit zeros (slack ropes) are removed first: with
    them SuperLU took 149 s instead of 0.52 s on one matrix. Inside a
    relaxation SuperLU's time still varies widely from matrix to matrix
    (0.5 s to about 50 s per factorisation at 297,675 DOFs, 0.03 s to 0.5 s
    at 29,403). ``"amg"`` uses smoothed-aggregation multigrid with the
    three nodal translations as near-null space as the preconditioner; it
    suits soft nets only: on a taut net of nearly inextensible ropes the
    tangent is so anisotropic (axial over transverse stiffness = 1 / strain)
    that preconditioned CG needed about 2000 iterations at 29,403 DOFs.
    Other methods go to :func:`shellform.solvers.linear.factorize`.
    """

    def __init__(self, method: str, n: int, reuse: bool = True, cg_max: int | None = None,
                 coords: np.ndarray | None = None, dofs: np.ndarray | None = None, correct: bool = True):
        if method == "auto":
            method = "cholesky"
        if method == "nd" and coords is None:
            raise ModelError("relaxation: the nested-dissection solver needs the node coordinates")
        self.coords = coords
        self.dofs = np.arange(n) if dofs is None else np.asarray(dofs)
        self._perm = None
        self._lu = None
        self.method = method
        self.n = int(n)
        self.reuse = reuse
        self.cg_max = cg_max
        self._qd = None
        self._chol = None
        self._factor = None
        self._ml = None
        self._ready = False
        self.factorizations = 0
        self.cg_iterations = 0
        self.success_rate = 1.0  # running estimate that an attempt with the old factor converges
        self._passed = 0  # solves since the last attempt
        self.correct = correct
        self._kept = None  # the factorised matrix's values, in the order of its pattern
        self._correction = None
        self.corrected = 0  # solves by CG with the kept factor corrected on a changed region

    @property
    def iteration_budget(self) -> int:
        if self.cg_max is not None:
            return int(self.cg_max)
        return iteration_budget(self.method, self.n)

    def _worth_an_attempt(self) -> bool:
        """Whether to try CG with the kept factor before refactorising."""
        if not (self.reuse and self._ready and self.iteration_budget > 0):
            return False
        if self.success_rate >= 0.5 or self._passed >= 3:
            self._passed = 0
            return True
        self._passed += 1
        return False

    def _factorize(self, A: sp.csr_matrix) -> None:
        self._ready = False
        if self.method == "ldl":
            import qdldl

            upper = sp.triu(A, format="csc")
            try:
                if self._qd is None:
                    self._qd = qdldl.Solver(upper)
                else:
                    self._qd.update(upper)
            except (RuntimeError, ValueError) as exc:
                self._qd = None
                raise SingularMatrixError(f"LDL^T factorisation failed: {exc}") from None
        elif self.method == "cholesky":
            try:
                self._chol = CholeskyFactor(A, previous=self._chol)
            except SingularMatrixError:
                self._chol = None
                raise
        elif self.method == "nd":
            import scipy.sparse.linalg as spla

            if self._perm is None:
                self._perm = _dof_order(A, self.coords, self.dofs)
            p = self._perm
            self._lu = None  # free the old factor first: two at once would double the peak memory
            Ap = sp.csc_matrix(A[p][:, p])
            # slack ropes leave explicit zeros in the tangent's fixed pattern; SuperLU keeps
            # them in its structure and ran 300 times slower with them (149 s against 0.52 s
            # on the first matrix of a 316 x 316 net, the same nonzeros in the factor)
            Ap.eliminate_zeros()
            try:
                # SPD: no pivoting needed, so the nested-dissection order is kept as given
                self._lu = spla.splu(Ap, permc_spec="NATURAL", diag_pivot_thresh=0.0,
                                     options={"SymmetricMode": True})
            except RuntimeError as exc:
                raise SingularMatrixError(f"sparse factorisation failed: {exc}") from None
        elif self.method == "amg":
            import pyamg

            n = A.shape[0]
            B = np.kron(np.ones((n // 3, 1)), np.eye(3)) if n % 3 == 0 else None
            M = A.tobsr(blocksize=(3, 3)) if n % 3 == 0 else A
            self._ml = pyamg.smoothed_aggregation_solver(M, B=B, symmetry="symmetric", max_coarse=1000)
            self._vcycle = self._ml.aspreconditioner(cycle="V")
        else:
            self._factor = factorize(A, self.method)
        self.factorizations += 1
        self._ready = True
        if self.correct and self.method != "amg":
            self._keep(A)

    def _keep(self, A: sp.csr_matrix) -> None:
        """Remember the factorised values, to find later where a matrix has changed from them."""
        if self._correction is None or not self._correction.fits(A):
            try:
                # three DOFs to a node (rope nets); for other layouts the groups are only coarser or finer
                node_of = np.unique(self.dofs // 3, return_inverse=True)[1]
                self._correction = LocalCorrection(A, node_of) if node_of.size == A.shape[0] else None
            except ValueError:
                self._correction = None
        self._kept = A.data.copy() if self._correction is not None else None

    def _attempt(self, A, b, prec, rtol):
        """Conjugate gradients within the iteration budget; returns ``(x, converged)``."""
        x, ok, its = _pcg(A, b, prec, rtol, self.iteration_budget)
        self.cg_iterations += its
        return x, ok

    def _attempt_preconditioner(self, A: sp.csr_matrix):
        """``(preconditioner, corrected)``: the old factor, corrected where ``A`` changed from it.

        The preconditioner is None when a refactorisation is due.
        """
        if self._kept is None or not self._correction.fits(A):
            return self._precondition, False
        prec = self._correction.preconditioner(A, self._kept, self._precondition)
        return prec, prec is not None and prec != self._precondition

    def _precondition(self, b: np.ndarray) -> np.ndarray:
        if self.method == "ldl":
            return self._qd.solve(b)
        if self.method == "cholesky":
            return self._chol.solve(b)
        if self.method == "nd":
            x = np.empty_like(b)
            x[self._perm] = self._lu.solve(b[self._perm])
            return x
        if self.method == "amg":
            return self._vcycle @ b
        return self._factor.solve(b)

    def solve(self, A: sp.csr_matrix, b: np.ndarray, rtol: float) -> np.ndarray:
        """Solve ``A x = b`` to relative residual ``rtol`` (or exactly after a refactorisation)."""
        prec, corrected = self._attempt_preconditioner(A) if self._worth_an_attempt() else (None, False)
        if prec is not None:
            x, ok = self._attempt(A, b, prec, rtol)
            self.success_rate = 0.7 * self.success_rate + 0.3 * float(ok)
            if ok:
                self.corrected += int(corrected)
                return x
        self._factorize(A)
        if self.method == "amg":
            x, ok, its = _pcg(A, b, self._precondition, min(rtol, 1e-8), 400)
            self.cg_iterations += its
            if not ok:
                raise SingularMatrixError("AMG-preconditioned CG did not converge")
        else:
            x = self._precondition(b)
            res = b - A @ x
            if float(np.linalg.norm(res)) > rtol * float(np.linalg.norm(b)):
                x = x + self._precondition(res)  # one step of iterative refinement
        if not np.all(np.isfinite(x)):
            self._ready = False
            raise SingularMatrixError("linear solve produced non-finite values")
        return x


def nested_dissection(graph: sp.csr_matrix, coords: np.ndarray, leaf: int = 64) -> np.ndarray:
    """Nested-dissection order of the vertices of a graph embedded in space.

    Each part is cut across its longest extent at the median coordinate; the
    vertices on one side with a neighbour on the other form the separator,
    numbered after both halves, which are ordered the same way (parts of at
    most ``leaf`` vertices keep their order). On a mesh-like surface graph of
    ``N`` vertices the separators have ``O(sqrt(N))`` vertices, so a sparse
    factorisation in this order fills ``O(N log N)`` entries.

    Parameters
    ----------
    graph : sparse matrix, shape (n, n)
        Symmetric adjacency (its pattern is used).
    coords : ndarray, shape (n, d)
        Vertex positions.

    Returns
    -------
    ndarray of int, shape (n,)
        The vertices in elimination order.
    """
    G = sp.csr_matrix(graph)
    n = G.shape[0]
    side = np.zeros(n, dtype=np.int8)
    order = []
    # explicit stack instead of recursion: (vertices, is_separator_block)
    stack = [(np.arange(n), False)]
    while stack:
        idx, done = stack.pop()
        if done or len(idx) <= leaf:
            order.append(idx)
            continue
        x = coords[idx]
        axis = int(np.argmax(np.ptp(x, axis=0)))
        cut = np.median(x[:, axis])
        left = x[:, axis] <= cut
        if left.all() or not left.any():
            left = np.arange(len(idx)) < len(idx) // 2
        a, b = idx[left], idx[~left]
        side[b] = 1
        touches = (G[a] @ side.astype(float)) > 0  # a-vertices with a neighbour in b
        side[b] = 0
        sep = a[touches]
        a = a[~touches]
        # popped last-in first-out: a and b are ordered before their separator
        stack.append((sep, True))
        stack.append((b, False))
        stack.append((a, False))
    # the stack visits a, then b, then the separator for every part
    return np.concatenate(order) if order else np.zeros(0, dtype=np.int64)


def _dof_order(A: sp.csr_matrix, q: np.ndarray, free: np.ndarray) -> np.ndarray:
    """A nested-dissection order of the unknowns of ``A`` (free DOFs, three per node at most).

    The free DOFs are grouped by node (DOF index // 3) in their sorted
    order; nodes are ordered by :func:`nested_dissection` on the graph of
    ``A`` at node level with coordinates from ``q``.
    """
    # unknown k of A is DOF free[k]
    node = free // 3
    nodes, local = np.unique(node, return_inverse=True)
    P = sp.csr_matrix((np.ones(len(free)), (np.arange(len(free)), local)), shape=(len(free), len(nodes)))
    Gn = (P.T @ (abs(A) @ P)).tocsr()
    coords = q[: 3 * (int(nodes.max()) + 1)].reshape(-1, 3)[nodes]
    order_nodes = nested_dissection(Gn, coords)
    rank = np.empty(len(nodes), dtype=np.int64)
    rank[order_nodes] = np.arange(len(nodes))
    return np.lexsort((free, rank[local]))


def _with_values(A: sp.csr_matrix, data: np.ndarray) -> sp.csr_matrix:
    """A CSR matrix of ``A``'s pattern with the values ``data``, sharing its index arrays.

    Only the values of a tangent change from step to step; a full copy would
    also copy the indices, 0.2 s each time at 10^6 nodes.
    """
    return sp.csr_matrix((data, A.indices, A.indptr), shape=A.shape)


def _pcg(A, b, prec, rtol, maxiter):
    """Preconditioned conjugate gradients from zero; returns ``(x, converged, iterations)``.

    Every iterate is a descent direction of the quadratic model, so even an
    unconverged result could be used; we still ask for ``rtol``.
    """
    x = np.zeros_like(b)
    r = b.copy()
    nb = float(np.linalg.norm(b))
    if nb == 0.0:
        return x, True, 0
    z = prec(r)
    p = z.copy()
    rz = float(r @ z)
    for k in range(1, maxiter + 1):
        Ap = A @ p
        pAp = float(p @ Ap)
        if not (pAp > 0 and np.isfinite(pAp)):
            return x, False, k
        a = rz / pAp
        x += a * p
        r -= a * Ap
        if float(np.linalg.norm(r)) <= rtol * nb:
            return x, True, k
        z = prec(r)
        rz_new = float(r @ z)
        p = z + (rz_new / rz) * p
        rz = rz_new
    return x, False, maxiter


# ---------------------------------------------------------------------------
# the driver
# ---------------------------------------------------------------------------
def relax(
    system,
    q0: np.ndarray | None = None,
    *,
    scheme: str = "implicit",
    v0: np.ndarray | None = None,
    lam: float = 1.0,
    mu: float = 0.0,
    extra_mass=None,
    damping: float | None = None,
    rtol: float = 1e-6,
    velocity_tol: float | None = None,
    acceleration_tol: float | None = None,
    dt: float | None = None,
    max_iterations: int | None = None,
    max_wall_time: float | None = None,
    spent_s: float = 0.0,
    linear_solver: str = "auto",
    stiffness_continuation: bool = True,
    slack_active_set: bool = True,
    front_sweeps: bool = True,
    factor_correction: bool = True,
    slack_settling: bool = True,
    step_repair: bool = True,
    start: str = "auto",
    callback: Callable[[RelaxationProgress], bool | None] | None = None,
    progress_every: int | None = None,
) -> RelaxationResult:
    """Let a net of masses and ropes fall to rest in its hanging shape.

    Parameters
    ----------
    system : System
        Ropes (and bars) with their loads; self-weight enters through the
        System's gravity effect. Constrained DOFs are suspension points.
    q0 : ndarray, optional
        Start state (all DOFs); the reference configuration by default (the
        flat planform). Constrained DOFs are set to their prescribed values.
        A ``q`` saved from a :class:`RelaxationProgress` resumes a run.
    scheme : {"implicit", "rk4", "kinetic"}
        See the module docstring.
    v0 : ndarray, optional
        Start velocity of every DOF (explicit schemes; default rest). With the
        ``q`` and ``v`` of a :class:`RelaxationProgress` an explicit run
        continues on the same trajectory. The implicit scheme starts from rest.
    lam, mu : float
        Load factor and prescribed-displacement parameter.
    extra_mass : float or array_like, optional
        Extra nodal inertia [kg] added to ``Structure.nodal_mass()``.
    damping : float, optional
        Viscous damping per unit mass ``c_i / m_i`` [1/s] (``rk4``; the implicit
        scheme adds it to the pseudo-time term). Default
        ``2 sqrt(g / L)``: critical damping of a pendulum of the net's size.
    rtol : float
        Default tolerances: acceleration ``rtol * g`` and velocity
        ``rtol * sqrt(g L)``, with ``g`` the largest load-over-mass of a node
        and ``L`` the size of the net.
    velocity_tol, acceleration_tol : float, optional
        Explicit tolerances [m/s], [m/s^2]; every node must meet both.
    dt : float, optional
        Time step of the explicit schemes (default: 90 % of the stability
        bound) or the first pseudo time step of the implicit one.
    max_iterations : int, optional
        Give up after this many steps (default 2,000,000 explicit, 500 implicit).
    max_wall_time : float, optional
        Give up after this many seconds.
    spent_s : float
        Seconds already spent on the same job before this call (a caller's
        preparation, such as hanging a coarse net first): counted in the
        result's and the progress reports' ``wall_time_s`` and against
        ``max_wall_time``.
    linear_solver : {"auto", "cholesky", "ldl", "nd", "amg", "direct", "lu"}
        Linear solver of the implicit scheme (see :class:`_SPDSolve`).
    stiffness_continuation : bool
        Implicit scheme only: reach the equilibrium through a sequence of
        softer nets (EA scaled by 10^-k, each stage started from the previous
        one). Nearly inextensible ropes make the potential so stiff that a
        quadratic model is accurate only for tiny steps while the net is far
        from its shape; soft ropes let the early steps be large. The last
        stage has the true EA, so the equilibrium is the same.
    slack_active_set : bool
        Implicit scheme only: solve each step again with the slack ropes it
        would stretch modelled as taut (:func:`_engage_slack_ropes`, at most
        two more solves per step). A slack rope has no stiffness, so a plain
        step overshoots wherever it pulls one taut and the line search must
        cut it. On the benchmark nets the active set halves the number of
        steps but not the number of factorisations, so the wall time stays
        about the same (``benchmarks/results/bench_mra.md``).
    front_sweeps : bool
        Implicit scheme only: after a step that leaves only a few nodes far
        from balance, take Newton steps on the patch of nodes around them with
        the rest of the net held (:func:`_sweep_fronts`). Nets of axial
        members under constant loads only, and with ``slack_active_set``;
        ignored otherwise.
    factor_correction : bool
        Implicit scheme only: before refactorising, try the kept factor
        corrected by an exact solve on the nodes whose tangent entries changed
        since it was made (:class:`~shellform.solvers.local_correction.LocalCorrection`).
    slack_settling : bool
        Implicit scheme only: when a step gets ropes' slack state wrong
        (slack ropes it stretches outside its active set, taut ones it
        shortens below their rest length), settle them on the patch of nodes
        around them (:func:`_settle_slack_set`). Needs
        ``slack_active_set``; like the front sweeps, only for nets of axial
        members under constant loads.
    step_repair : bool
        Implicit scheme only: when a few ropes make the whole net's step
        overshoot, keep the full step and relax the patch of nodes around
        them from there instead of cutting the step
        (:func:`_repair_full_step`). Same conditions as ``slack_settling``.
    start : {"auto", "reference", "force_density"}
        Where to start when ``q0`` is not given: the reference state (the
        flat planform, as in the MRA paper) or the force-density shape of
        :func:`force_density_start` (one scalar linear solve; the net then
        skips its free fall). ``"auto"``: the force-density shape for the
        implicit scheme, the reference state for the explicit ones.
    callback : callable, optional
        Called with a :class:`RelaxationProgress` every ``progress_every``
        iterations; returning True stops the run (reported as not converged).
    progress_every : int, optional
        Default 1 for the implicit scheme, 2000 for the explicit ones.

    Returns
    -------
    RelaxationResult
    """
    if scheme not in SCHEMES:
        raise ModelError(f"relaxation: unknown scheme {scheme!r}; expected one of {SCHEMES}")
    if start not in START_STATES:
        raise ModelError(f"relaxation: unknown start {start!r}; expected one of {START_STATES}")
    if not (np.isfinite(spent_s) and spent_s >= 0):
        raise ModelError(f"relaxation: spent_s must be a finite, non-negative time, got {spent_s!r}")
    t0 = time.perf_counter() - spent_s
    st = _setup(system, q0, lam, mu, extra_mass, rtol, velocity_tol, acceleration_tol, damping, v0)
    if progress_every is None:
        progress_every = 1 if scheme == "implicit" else 2000
    if max_iterations is None:
        max_iterations = 500 if scheme == "implicit" else 2_000_000
    if q0 is not None:
        st.start = "given"
    fd_start = q0 is None and (start == "force_density" or (start == "auto" and scheme == "implicit"))
    if fd_start and scheme != "implicit":
        q_fd = force_density_start(system, lam, base=st.q)
        if q_fd is not None:
            st.q, st.start = q_fd, "force_density"
    args = (system, st, lam, dt, int(max_iterations), max_wall_time, linear_solver, callback,
            max(int(progress_every), 1), t0)
    if scheme == "implicit":
        return _run_implicit(*args, continuation=stiffness_continuation, fd_start=fd_start,
                             active_set=slack_active_set, sweeps=front_sweeps, correction=factor_correction,
                             settling=slack_settling, repair=step_repair)
    return {"rk4": _run_rk4, "kinetic": _run_kinetic}[scheme](*args)


class _Monitor:
    """Shared bookkeeping: tolerances, history, callback, finishing."""

    def __init__(self, system, st, scheme, lam, callback, every, t0, max_wall_time):
        self.system, self.st, self.scheme, self.lam = system, st, scheme, lam
        self.callback, self.every, self.t0, self.max_wall_time = callback, every, t0, max_wall_time
        self.history = {"iteration": [], "max_velocity": [], "max_acceleration": [], "residual_norm": []}
        self.n_res = 0
        self.n_fact = 0
        self.n_cg = 0
        self.n_local = 0
        self.n_corrected = 0
        self.n_repaired = 0
        self.rejected = 0

    def measure(self, v_free, r_free, a_free=None):
        """Nodal maxima; the acceleration is ``-r / m`` unless given."""
        vmax = _nodal_max(self.system, v_free)
        amax = _nodal_max(self.system, (-r_free / self.st.m) if a_free is None else a_free)
        return vmax, amax, float(np.linalg.norm(r_free))

    def converged(self, vmax, amax) -> bool:
        return vmax <= self.st.v_tol and amax <= self.st.a_tol

    def full(self, x_free, base=None):
        """A vector over all DOFs: ``x_free`` at the free ones, ``base`` (or zero) elsewhere."""
        out = np.zeros(self.system.n_dof) if base is None else base.copy()
        out[self.system.free] = x_free
        return out

    def tick(self, it, t, vmax, amax, rnorm, q_free, v_free) -> str | None:
        """Record, call back with the current state; return a reason to stop, if any."""
        if it % self.every == 0:
            for k, val in zip(self.history, (it, vmax, amax, rnorm)):
                self.history[k].append(val)
            if self.callback is not None:
                info = RelaxationProgress(self.scheme, it, t, vmax, amax, rnorm, time.perf_counter() - self.t0,
                                          q=self.full(q_free, self.st.q), v=self.full(v_free))
                if self.callback(info):
                    return f"stopped by the progress callback after {it} iterations"
        if self.max_wall_time is not None and time.perf_counter() - self.t0 > self.max_wall_time:
            return f"not converged within the wall-time limit of {self.max_wall_time:g} s ({it} iterations)"
        return None

    def finish(self, q_free, v_free, success, message, it, t, h, vmax, amax, rnorm):
        q = self.full(q_free, self.st.q)  # constrained DOFs at their prescribed values
        v = self.full(v_free)
        return RelaxationResult(
            q=q, v=v, success=success, message=message, scheme=self.scheme, iterations=it,
            max_velocity=vmax, max_acceleration=amax, residual_norm=rnorm,
            velocity_tol=self.st.v_tol, acceleration_tol=self.st.a_tol, time=t, time_step=h,
            wall_time_s=time.perf_counter() - self.t0, reactions=self.system.reactions(q, self.lam),
            residual_evaluations=self.n_res, factorizations=self.n_fact, rejected_steps=self.rejected,
            linear_iterations=self.n_cg, local_steps=self.n_local, corrected_solves=self.n_corrected,
            repaired_steps=self.n_repaired,
            history=self.history, start=self.st.start,
        )


def _converged_message(mon, it, vmax, amax):
    msg = (f"at rest after {it} iterations: max nodal velocity {vmax:.3e} <= {mon.st.v_tol:.3e} m/s, "
           f"max nodal acceleration {amax:.3e} <= {mon.st.a_tol:.3e} m/s^2")
    if mon.st.a_tol > mon.st.a_tol_asked:
        msg += (f" (acceleration tolerance raised from {mon.st.a_tol_asked:.3e} to the round-off level of "
                "the rope forces)")
    return msg


def _not_finite_message(it, h):
    return (f"diverged at iteration {it}: the state is no longer finite (time step {h:.3e} s); "
            "reduce the time step")


def _explicit_step_size(system, st, dt, scheme):
    if dt is not None:
        if not (dt > 0 and np.isfinite(dt)):
            raise ModelError(f"relaxation: time step must be positive and finite, got {dt}")
        return float(dt)
    return _bound_step(system, st.q, st.m_node, scheme, st.damping if scheme == "rk4" else 0.0)


def _run_rk4(system, st, lam, dt, max_it, max_wall, linear_solver, callback, every, t0):
    mon = _Monitor(system, st, "rk4", lam, callback, every, t0, max_wall)
    h = _explicit_step_size(system, st, dt, "rk4")
    free = system.free
    q = st.q.copy()
    m, c = st.m, st.damping
    L_big = 1e6 * st.L_ref

    def acc(qf, vf):
        q[free] = qf
        r = system.residual(q, lam)[free]
        mon.n_res += 1
        return (-r - c * m * vf) / m, r

    qf = st.q[free].copy()
    vf = st.v0.copy()
    qf_prev, vf_prev = qf, vf
    t = 0.0
    vmax = amax = rnorm = np.nan
    for it in range(max_it + 1):
        a1, r = acc(qf, vf)
        vmax, amax, rnorm = mon.measure(vf, r, a1)
        if not (np.isfinite(amax) and np.isfinite(vmax)) or np.max(np.abs(qf)) > L_big:
            return mon.finish(qf_prev, vf_prev, False, _not_finite_message(it, h), it, t, h, np.nan, np.nan, np.nan)
        if mon.converged(vmax, amax):
            return mon.finish(qf, vf, True, _converged_message(mon, it, vmax, amax), it, t, h, vmax, amax, rnorm)
        if it == max_it:
            break
        stop = mon.tick(it, t, vmax, amax, rnorm, qf, vf)
        if stop:
            return mon.finish(qf, vf, False, stop, it, t, h, vmax, amax, rnorm)
        qf_prev, vf_prev = qf, vf
        v2 = vf + 0.5 * h * a1
        a2, _ = acc(qf + 0.5 * h * vf, v2)
        v3 = vf + 0.5 * h * a2
        a3, _ = acc(qf + 0.5 * h * v2, v3)
        v4 = vf + h * a3
        a4, _ = acc(qf + h * v3, v4)
        qf = qf + (h / 6.0) * (vf + 2.0 * v2 + 2.0 * v3 + v4)
        vf = vf + (h / 6.0) * (a1 + 2.0 * a2 + 2.0 * a3 + a4)
        t += h
    return mon.finish(qf, vf, False, _limit_message(mon, max_it, vmax, amax), max_it, t, h, vmax, amax, rnorm)


def _limit_message(mon, it, vmax, amax):
    return (f"not converged in {it} iterations: max nodal velocity {vmax:.3e} (tolerance {mon.st.v_tol:.3e}), "
            f"max nodal acceleration {amax:.3e} (tolerance {mon.st.a_tol:.3e})")


def _run_kinetic(system, st, lam, dt, max_it, max_wall, linear_solver, callback, every, t0):
    mon = _Monitor(system, st, "kinetic", lam, callback, every, t0, max_wall)
    h = _explicit_step_size(system, st, dt, "kinetic")
    free = system.free
    q = st.q.copy()
    m = st.m
    L_big = 1e6 * st.L_ref

    def force(qf):
        q[free] = qf
        mon.n_res += 1
        return system.residual(q, lam)[free]

    qf = st.q[free].copy()
    v = st.v0.copy()  # velocity at the half step t - h/2
    qf_prev = qf
    r = force(qf)
    ke_prev = 0.5 * float(np.dot(m * v, v))
    t = 0.0
    vmax = amax = rnorm = np.nan
    for it in range(max_it + 1):
        a = -r / m
        vmax, amax, rnorm = mon.measure(v, r, a)
        if not (np.isfinite(amax) and np.isfinite(vmax)) or np.max(np.abs(qf)) > L_big:
            return mon.finish(qf_prev, np.zeros_like(qf), False, _not_finite_message(it, h), it, t, h,
                              np.nan, np.nan, np.nan)
        if mon.converged(vmax, amax):
            return mon.finish(qf, v, True, _converged_message(mon, it, vmax, amax), it, t, h, vmax, amax, rnorm)
        if it == max_it:
            break
        stop = mon.tick(it, t, vmax, amax, rnorm, qf, v)
        if stop:
            return mon.finish(qf, v, False, stop, it, t, h, vmax, amax, rnorm)
        qf_prev = qf
        v_new = v + h * a
        q_new = qf + h * v_new
        ke = 0.5 * float(np.dot(m * v_new, v_new))
        if ke < ke_prev:
            # the kinetic energy peaked during the last steps: go back to the peak
            # (quadratic interpolation of the trajectory, Barnes' correction) and
            # restart from rest there
            qf = q_new - 1.5 * h * v_new + 0.5 * h * h * a
            v = np.zeros_like(qf)
            ke_prev = 0.0
        else:
            qf, v = q_new, v_new
            ke_prev = ke
        r = force(qf)
        t += h
    return mon.finish(qf, v, False, _limit_message(mon, max_it, vmax, amax), max_it, t, h, vmax, amax, rnorm)


def _axial_effects(system):
    return [e for e in system.effects if all(hasattr(e, a) for a in ("conn", "EA", "L"))]


def _with_stiffness_scale(system, scale: float):
    """A shallow copy of ``system`` whose axial members have ``scale`` times their EA.

    The copy shares the sparsity patterns (they do not depend on EA) and leaves
    the caller's System untouched.
    """
    view = copy.copy(system)
    effects = []
    for e in system.effects:
        if all(hasattr(e, a) for a in ("conn", "EA", "L")):
            e = copy.copy(e)
            e.EA = e.EA * scale
        effects.append(e)
    view.effects = tuple(effects)
    return view


#: an intermediate stiffness stage ends when every nodal acceleration is below this many g: it
#: only has to land near its equilibrium, and a tighter tolerance ends it with a crawl of slack fronts
STAGE_TOLERANCE = 0.3


def _continuation_scales(system, st, lam) -> list[float]:
    """Stiffness scales of the EA continuation, ending at 1.

    The first stage makes the ropes soft enough to stretch about 10 % under an
    estimate of the rope tension (the largest nodal load times the number of
    ropes across the net, over four); each later stage is ten times stiffer.
    When most ropes are already taut at the start, the first stage is the one
    whose expected strain matches their median strain.
    """
    axial = _axial_effects(system)
    if not axial:
        return [1.0]
    EA = np.concatenate([e.EA for e in axial])
    L = np.concatenate([e.L for e in axial])
    f = np.linalg.norm(system.external_force(lam).reshape(-1, 3), axis=1)
    tension = float(f.max()) * max(st.L_ref / float(np.mean(L)), 1.0) / 4.0
    if tension <= 0:
        return [1.0]
    s0 = 10.0 * tension / float(np.median(EA))
    # A start that already hangs (most ropes taut, e.g. on a surface close to the
    # shape) skips the stages softer than its own rope strains: a soft stage would
    # only stretch the net away from where it starts.
    strain = np.concatenate([(e._geometry(st.q)[1] - e.L) / e.L for e in axial])
    taut = strain > 0
    if taut.mean() >= 0.5:
        s0 = max(s0, 0.1 * s0 / max(float(np.median(strain[taut])), 1e-12))
    if s0 >= 0.1:
        return [1.0]
    scales = []
    while s0 < 1.0:
        scales.append(s0)
        s0 *= 10.0
    return scales + [1.0]


def _run_implicit(system, st, lam, dt, max_it, max_wall, linear_solver, callback, every, t0, continuation=True,
                  fd_start=False, active_set=True, sweeps=True, correction=True, settling=True, repair=True):
    mon = _Monitor(system, st, "implicit", lam, callback, every, t0, max_wall)
    # without the active set a step of the whole net overshoots where it pulls slack ropes
    # taut, and the patches' steps, taken from there, only add to it (docs/theory-mra.md)
    graph = NodeGraph(system) if (sweeps or settling or repair) and active_set and patchable(system) else None
    free = system.free
    solver = _SPDSolve(linear_solver, free.size, coords=st.q, dofs=free, correct=correction)
    scales = _continuation_scales(system, st, lam) if continuation else [1.0]
    if fd_start:
        # the force-density shape in balance with the first stage's stiffness: the softest
        # stage then starts near its equilibrium instead of falling from the planform
        q_fd = force_density_start(system, lam, scales[0], base=st.q)
        if q_fd is not None:
            st.q, st.start = q_fd, "force_density"
    # the first pseudo step is a free fall of about 1 % of the net's size
    h = float(dt) if dt is not None else np.sqrt(0.02 * st.L_ref / st.g_ref)
    q = st.q.copy()
    total = {"it": 0, "t": 0.0}
    diag_pos = [None]
    for k, scale in enumerate(scales):
        last = k == len(scales) - 1
        view = system if scale == 1.0 else _with_stiffness_scale(system, scale)
        # intermediate stages only need to land near their equilibrium
        a_tol = st.a_tol if last else max(st.a_tol, STAGE_TOLERANCE * st.g_ref)
        v_tol = st.v_tol if last else np.inf
        out = _ptc(view, mon, solver, q, h, lam, a_tol, v_tol, max_it, total, diag_pos, active_set, graph,
                   sweeps, settling, repair)
        q, h, v, success, message, vmax, amax, rnorm = out
        mon.n_fact = solver.factorizations
        mon.n_cg = solver.cg_iterations
        mon.n_corrected = solver.corrected
        if not success or last:
            if not last:
                message = f"stiffness stage {k + 1} of {len(scales)} (EA x {scale:.1e}): {message}"
            return mon.finish(q[free], v, success, message, total["it"], total["t"], h, vmax, amax, rnorm)
        # a stiffer net moves little from here: restart with a moderate pseudo step
        h = min(h, np.sqrt(st.L_ref / st.g_ref))


def _ptc(system, mon, solver, q, h, lam, a_tol, v_tol, max_it, total, diag_pos, active_set=True, graph=None,
         sweeps=True, settling=True, repair=True):
    """Pseudo-transient continuation on one System; returns the final state and status."""
    st = mon.st
    free = system.free
    m = st.m
    h_max = 1e12 * np.sqrt(st.L_ref / st.g_ref)

    def residual(qq):
        mon.n_res += 1
        return system.residual(qq, lam)[free]

    r = residual(q)
    v = np.zeros(free.size)
    K = None
    # tension-only members whose slack state the step's model can take into account
    ropes = [e for e in system.effects if hasattr(e, "stretched_by")] if active_set else []
    engaged = None
    vmax, amax, rnorm = mon.measure(v, r)
    f_ext = system.external_force(lam)
    f_scale = max(float(np.linalg.norm(f_ext[free])), rnorm, 1e-300)
    # changes of the potential below this are round-off (work of the loads over one ulp of the positions)
    e_floor = 1e3 * np.finfo(float).eps * float(np.abs(f_ext).sum()) * max(st.L_ref, float(np.abs(q).max()))
    tries = 0
    while True:
        if not np.isfinite(rnorm):
            return q, h, v, False, f"the residual is not finite at iteration {total['it']}", np.nan, np.nan, np.nan
        if vmax <= v_tol and amax <= a_tol:
            return q, h, v, True, _converged_message(mon, total["it"], vmax, amax), vmax, amax, rnorm
        if total["it"] >= max_it:
            return q, h, v, False, _limit_message(mon, total["it"], vmax, amax), vmax, amax, rnorm
        if tries > 60:
            return (q, h, v, False, f"iteration {total['it']}: no pseudo time step reduced the potential "
                    f"(last step {h:.3e} s); the net may be a mechanism", vmax, amax, rnorm)
        if K is None:
            K = system.tangent_free(q)
            K.sort_indices()
            if diag_pos[0] is None:
                diag_pos[0] = _diagonal_positions(K)
        # backward-Euler step from rest with viscous damping: (M/h^2 + C/h + K) dq = -r
        A = _with_values(K, K.data.copy())
        A.data[diag_pos[0]] += (1.0 / h**2 + st.damping / h) * m
        # inexact steps far from equilibrium, accurate ones close to it
        eta = min(1e-2, max(1e-10, float(np.sqrt(rnorm / f_scale))))
        try:
            if ropes:
                p, engaged = _engage_slack_ropes(system, ropes, solver, A, r, q, eta, engaged,
                                                 graph=graph if settling else None)
            else:
                p = solver.solve(A, -r, eta)
        except SingularMatrixError:
            mon.rejected += 1
            h *= 0.25
            tries += 1
            continue
        slope = float(r @ p)
        if not slope < 0:
            mon.rejected += 1
            h *= 0.25
            tries += 1
            continue
        pred = slope + 0.5 * float(p @ (K @ p))
        if ropes:
            # the step was solved in the ropes' piecewise model, not the tangent's: judged
            # against the tangent alone, a step that lets taut ropes go slack seems to
            # predict a rise, and the pseudo step was held for many steps at 4e5 nodes
            dq = np.zeros(system.n_dof)
            dq[free] = p
            pred += sum(float(e.switch_model_change(q, dq).sum()) for e in ropes)
        tiny = abs(pred) <= e_floor
        def at(a, p=p):
            qq = q.copy()
            qq[free] += a * p
            rr = residual(qq)
            return energy_change(system, q, qq, lam), rr, float(rr @ p)

        first = at(1.0)
        dE1, r1, d1 = first
        repaired = None
        # only a full step that the line search would cut
        if repair and graph is not None and ropes and not tiny and np.all(np.isfinite(r1)) and np.isfinite(dE1) \
                and not _sufficient_decrease(dE1, d1, slope):
            repaired = _repair_full_step(system, graph, st, ropes, q, p, r1, dE1, slope, h, f_ext, e_floor)
        if repaired is not None:
            q_new, r_try, dE, excess = repaired
            alpha = 1.0
            mon.n_repaired += 1
            # outside the patch the step followed its model
            rho = (dE1 - excess) / pred if pred < 0 else 0.5
        else:
            alpha, dE, r_try = _line_search(at, slope, rnorm, tiny, first=first)
            rho = dE / pred if (pred < 0 and alpha == 1.0) else 0.5
            q_new = q.copy()
            q_new[free] += alpha * p
        if alpha == 0.0:
            mon.rejected += 1
            h *= 0.25
            tries += 1
            continue
        tries = 0
        v = alpha * p / h
        q = q_new
        r = r_try
        K = None
        total["t"] += h
        total["it"] += 1
        if alpha == 1.0 and (rho > 0.75 or tiny):
            h = min(4.0 * h, h_max)
        elif alpha < 0.1:
            h *= 0.25
        elif rho < 0.25:
            # a partial step is progress; only a poor quadratic model shortens the pseudo step
            h *= 0.5
        if graph is not None and sweeps:
            mon.n_local += _sweep_fronts(system, graph, st, q, r, h, f_ext, a_tol, e_floor)
        vmax, amax, rnorm = mon.measure(v, r)
        stop = mon.tick(total["it"], total["t"], vmax, amax, rnorm, q[free], v)
        if stop:
            return q, h, v, False, stop, vmax, amax, rnorm


#: a front sweep runs while the nodes above FRONT_LEVEL times the largest nodal
#: acceleration are at most FRONT_SHARE of the free nodes ...
FRONT_LEVEL = 0.3
FRONT_SHARE = 0.01
#: ... on the nodes within FRONT_RINGS members of them, at most FRONT_STEPS times per step
FRONT_RINGS = 4
FRONT_STEPS = 3


def _sweep_fronts(system, graph, st, q, r, h, f_ext, a_tol, e_floor) -> int:
    """Newton steps on the patches around the few nodes that hold a relaxation back.

    Late in a relaxation the out-of-balance force sits at a few nodes along
    the fronts between taut and slack regions, and a step of the whole net
    moves such a front by about one node. While the nodes above
    ``FRONT_LEVEL`` times the largest acceleration are few (at most
    ``FRONT_SHARE`` of the free nodes), this takes a pseudo-time step of the
    same form as the global one, ``(M/h^2 + C/h + K) dq = -r``, on the nodes
    within ``FRONT_RINGS`` members of them (:class:`~shellform.solvers.patch.Patch`,
    the rest of the net held), with the same line search on the whole net's
    potential, so every accepted step lowers it. A step after which the
    largest acceleration has not fallen is undone and ends the sweep: its
    patch has set up ropes that the next step of the whole net would have to
    undo. ``q`` and ``r`` (free DOFs) are updated in place, ``r`` exactly
    from the patch's members. Returns the number of steps kept.
    """
    free_index = graph.free_index
    steps = 0
    undo = None
    a_last = np.inf
    for _ in range(FRONT_STEPS + 1):
        acc = _nodal_norms(system, r / st.m)
        amax = float(acc.max())
        if undo is not None and not amax < a_last:
            # the potential fell, but the imbalance grew: the patch's step set up ropes
            # the next step of the whole net would have to undo
            moving, q_old, index, r_old = undo
            q[moving] = q_old
            r[index] = r_old
            steps -= 1
            break
        if steps == FRONT_STEPS or not amax > a_tol:
            break
        a_last = amax
        hot = np.flatnonzero(acc > FRONT_LEVEL * amax)
        if hot.size > FRONT_SHARE * graph.n_free_nodes:
            break
        patch = Patch(system, graph, graph.within(hot, FRONT_RINGS), f_ext)
        if not patch.n_moving:
            break
        moving = patch.dofs[patch.moving]
        ql = q[patch.dofs]
        step = _patch_step(patch, st.m[free_index[moving]], ql, h, st.damping, e_floor)
        if step is None:
            break
        q1 = step[0]
        # the residual changes only at the patch's DOFs, by its members' change of force
        index = free_index[patch.dofs]
        held = index >= 0
        index = index[held]
        undo = (moving, q[moving].copy(), index, r[index].copy())
        q[moving] = q1[patch.moving]
        r[index] += (patch.internal_force(q1) - patch.internal_force(ql))[held]
        steps += 1
    return steps


def _patch_step(patch, m, ql, h, damping, e_floor):
    """One pseudo-time step ``(M/h^2 + C/h + K) dq = -r`` on a patch, the rest of the net held.

    ``m`` holds the masses of the patch's moving DOFs and ``ql`` the state of
    its local DOFs. The step goes through the same line search as the global
    one, on the whole net's potential, so it lowers it. Returns the new local
    state and the change of potential, or None when no step lowers it.
    """
    rl = patch.residual(ql)
    K = patch.tangent(ql)
    A = K + sp.diags((1.0 / h**2 + damping / h) * m)
    try:
        p = CholeskyFactor(A).solve(-rl)
    except SingularMatrixError:
        return None
    slope = float(rl @ p)
    if not (np.all(np.isfinite(p)) and slope < 0):
        return None
    tiny = abs(slope + 0.5 * float(p @ (K @ p))) <= e_floor

    def at(a):
        q1 = ql.copy()
        q1[patch.moving] += a * p
        r1 = patch.residual(q1)
        return patch.energy_change(ql, q1), r1, float(r1 @ p)

    alpha, dE, _ = _line_search(at, slope, float(np.linalg.norm(rl)), tiny)
    if alpha == 0.0:
        return None
    q1 = ql.copy()
    q1[patch.moving] += alpha * p
    return q1, dE


#: a full step is repaired when the ropes that hold REPAIR_COVER of its excess over the
#: step's model are at most REPAIR_SHARE of all ropes ...
REPAIR_COVER = 0.9
REPAIR_SHARE = 0.01
#: ... on the nodes within REPAIR_RINGS members of them, while their free DOFs are at most
#: REPAIR_PATCH of all, in at most REPAIR_STEPS patch steps
REPAIR_RINGS = 3
REPAIR_PATCH = 0.03
REPAIR_STEPS = 8


def _repair_full_step(system, graph, st, ropes, q, p, r1, dE1, slope, h, f_ext, e_floor):
    """The full step, with the patch around the few ropes that make it overshoot relaxed from there.

    The line search often cuts the whole net's step for the sake of a few
    ropes: late in a stiffness stage to about a half, for taut ropes with
    almost no tension at the edge of a slack region, whose small geometric
    stiffness lets the step move their nodes sideways by several per cent of
    their length. That stretches them by far more than their strain, energy
    that the step's quadratic model leaves out. The rest of the net follows
    the model, but the cut step gives it only part of its Newton step. Here
    the full step is kept, and the patch of nodes within
    :data:`REPAIR_RINGS` members of the ropes that hold
    :data:`REPAIR_COVER` of the excess
    (:meth:`~shellform.effects.axial.Rope.model_excess`) takes pseudo-time
    steps from it, the rest of the net held. It stops once the potential
    has fallen by the line search's sufficient decrease and the patch's
    largest acceleration is no larger than the largest outside it: a patch
    left far from balance holds the next step of the whole net back.

    Returns ``(q, r, dE, excess)`` -- the state, its residual (free DOFs),
    the change of potential from ``q`` and the repaired ropes' excess -- or
    None when the excess is not local or the patch does not make up for it.
    """
    free = system.free
    dq = np.zeros(system.n_dof)
    dq[free] = p
    excess = np.concatenate([e.model_excess(q, dq) for e in ropes])
    above = np.maximum(excess, 0.0)
    total = float(above.sum())
    if not total > 0:
        return None
    order = np.argsort(-excess)
    count = int(np.searchsorted(np.cumsum(above[order]), REPAIR_COVER * total)) + 1
    if count > REPAIR_SHARE * excess.size:
        return None
    worst = order[:count]
    conn = np.concatenate([e.conn for e in ropes])
    patch = Patch(system, graph, graph.within(np.unique(conn[worst]), REPAIR_RINGS), f_ext)
    if not 0 < patch.n_moving <= REPAIR_PATCH * free.size:
        return None
    q1 = q.copy()
    q1[free] += p
    ql0 = q1[patch.dofs]
    ql = ql0
    inside = graph.free_index[patch.dofs[patch.moving]]
    m = st.m[inside]
    outside = np.ones(free.size, dtype=bool)
    outside[inside] = False
    a_out = float(np.max(np.abs(r1[outside]) / st.m[outside], initial=0.0))
    dE = dE1
    for _ in range(REPAIR_STEPS):
        step = _patch_step(patch, m, ql, h, st.damping, e_floor)
        if step is None:
            break
        ql, change = step
        dE += change
        if dE <= ARMIJO * slope and float(np.max(np.abs(patch.residual(ql)) / m)) <= a_out:
            break
    if not dE <= ARMIJO * slope:
        return None
    q1[patch.dofs[patch.moving]] = ql[patch.moving]
    # the residual changes only at the patch's DOFs, by its members' change of force
    index = graph.free_index[patch.dofs]
    held = index >= 0
    r = r1.copy()
    r[index[held]] += (patch.internal_force(ql) - patch.internal_force(ql0))[held]
    return q1, r, dE, float(excess[worst].sum())


def _engage_slack_ropes(system, ropes, solver, A, r, q, eta, engaged=None, rounds=2, graph=None):
    """The pseudo-time step with the slack ropes it would stretch modelled as taut springs.

    The step's model treats a slack rope as absent, so a step that pulls one
    taut overshoots (the rope's energy ``1/2 (EA / L) (l - L)^2`` appears at
    once) and the line search cuts it. This is a primal-dual active-set
    iteration on the piecewise quadratic model instead: the slack ropes that
    the step lengthens past their rest length to first order join the model
    (:meth:`~shellform.effects.axial.Rope.engaged_terms`), the step is solved
    again, and the set is updated until it stops changing or after
    ``rounds`` more solves. ``engaged`` (a mask per rope effect, e.g. the
    previous step's final set) is where the set starts; ropes taut by now
    leave it. With a ``graph``, the step is then settled on the nodes around
    the ropes whose state it still gets wrong (:func:`_settle_slack_set`):
    slack ropes when the rounds end with a set that still changes, and taut
    ropes that the step shortens below their rest length, which the rounds
    do not model. Returns the step and its final set (None when empty).
    """
    free = system.free
    dq = np.zeros(system.n_dof)
    # the ropes' linear model at q serves every round and the settling: q does not change here
    geo = [e.linearised(q) for e in ropes]
    if engaged is not None:
        engaged = [m & slack for m, (n, gap, k, slack) in zip(engaged, geo)]
        if not any(m.any() for m in engaged):
            engaged = None
    p = None
    settled = False
    for _ in range(rounds + 1):
        used = engaged
        if engaged is None:
            p = solver.solve(A, -r, eta)
        else:
            A_set, g = _with_engaged(system, ropes, engaged, A, q)
            p = solver.solve(A_set, -(r + g[free]), eta)
        dq[free] = p
        masks = [e.stretched_by(q, dq, model) for e, model in zip(ropes, geo)]
        if used is None and not any(m.any() for m in masks) or \
                used is not None and all(np.array_equal(a, b) for a, b in zip(masks, used)):
            settled = True
            break
        engaged = masks if any(m.any() for m in masks) else None
    if graph is None:
        return p, (used if settled else engaged)
    if used is None:
        used = [np.zeros(len(e.L), dtype=bool) for e in ropes]
    # a settled set can still shorten taut ropes below their rest length: the step holds them as
    # springs that push, so they are released on the patch around them
    return _settle_slack_set(ropes, graph, A, r, q, p, used, geo)


def _with_engaged(system, ropes, engaged, A, q):
    """``A`` plus the springs of the ``engaged`` slack ropes, and their pulls (all DOFs).

    Only the engaged ropes are evaluated and added, at their positions in the
    tangent's fixed pattern: they are few, and a whole-net assembly of their
    terms (mostly zeros) cost 1.2 s per round at 10^6 nodes.
    """
    g = np.zeros(system.n_dof)
    out = _with_values(A, A.data.copy())
    for e, m in zip(ropes, engaged):
        members = np.flatnonzero(m)
        f, vals = e.engaged_blocks(q, members)
        g += scatter(system.n_dof, e.dofs[members], f)
        system.add_free_entries(out, e, e.hessian_entries(members), vals)
    return out, g


#: the ropes whose state a step gets wrong are settled on the nodes within SETTLE_RINGS
#: members of them, while their free DOFs are at most SETTLE_SHARE of
#: all, in at most SETTLE_STEPS local Newton steps: a line held sideways by a chain of barely
#: taut ropes is released a few ropes per step (docs/theory-mra.md)
SETTLE_RINGS = 3
SETTLE_SHARE = 0.3
SETTLE_STEPS = 40


def _settle_slack_set(ropes, graph, A, r, q, p, used, geo=None):
    """Settle the slack set of a step on the nodes around the ropes whose state it gets wrong.

    ``p`` was solved with every taut rope and the slack ropes of ``used``
    modelled as springs (:func:`_engage_slack_ropes`). It may stretch other
    slack ropes, or leave some of ``used`` unstretched: along slack fronts
    the rounds move the set by about one layer of ropes per round. It may
    also shorten taut ropes below their rest length, where their springs
    push, so a front of ropes going slack moves by one layer per step. Those
    ropes are few and local, so the step's model is solved on a patch, the
    nodes within :data:`SETTLE_RINGS` members of them, with the rest of the
    step held. The model is convex and piecewise quadratic: ``1/2 p.A p +
    r.p`` with the taut ropes' springs taken out of ``A``, plus ``sum 1/2
    (EA/L) (l - L + n.dp)_+^2`` over all ropes. Semismooth Newton on the
    patch solves it, each local step with the ropes it currently stretches
    as springs, until no rope changes state (at most :data:`SETTLE_STEPS`;
    a chain of taut ropes with almost no tension along a line that the step
    moves sideways is released from its ends, a few ropes per local step).
    The ropes outside the patch keep their state, as the step does not
    change there. ``geo`` is the ropes' ``linearised(q)``, when the caller
    has it. Returns the step and the set of the slack ropes it stretches
    (None when empty).
    """
    free_index = graph.free_index
    dq = np.zeros(free_index.size)
    dq[free_index >= 0] = p
    geo = [e.linearised(q) for e in ropes] if geo is None else geo

    def taut_after(e, n, gap, members):
        dd = e._end_difference(dq, e.dofs[members])
        return gap[members] + np.einsum("ij,ij->i", n[members], dd) > 0

    # the step was solved with the taut ropes and the slack ropes of ``used`` as springs
    modelled = [u | ~slack for u, (n, gap, k, slack) in zip(used, geo)]
    state = [taut_after(e, n, gap, slice(None)) for e, (n, gap, k, slack) in zip(ropes, geo)]

    def result(p):
        stretched = [s & slack for s, (n, gap, k, slack) in zip(state, geo)]
        return p, (stretched if any(m.any() for m in stretched) else None)

    wrong = [e.conn[a != b].ravel() for e, a, b in zip(ropes, state, modelled)]
    seeds = np.unique(np.concatenate(wrong))
    if not seeds.size:
        return result(p)
    nodes = graph.within(seeds, SETTLE_RINGS)
    rows = free_index[(3 * nodes[:, None] + np.arange(3)).ravel()]
    rows = np.sort(rows[rows >= 0])
    if rows.size > SETTLE_SHARE * p.size:
        return result(p)
    patch_dofs = np.flatnonzero(free_index >= 0)[rows]  # global DOF of each row
    local = np.full(free_index.size, -1, dtype=np.int64)  # local position of each global DOF on the patch
    local[patch_dofs] = np.arange(rows.size)
    A_rows = A[rows]
    A_loc = A_rows[:, rows]
    members = graph.members_of(nodes)
    p = p.copy()
    for _ in range(SETTLE_STEPS):
        # the model's gradient and Hessian on the patch: A holds every taut rope as a spring, so a
        # stretched slack rope adds one and a released taut rope takes its spring away
        grad = A_rows @ p + r[rows]
        blocks, block_dofs = [], []
        for e, (n, gap, k, slack), m, s in zip(ropes, geo, members, state):
            on = m[s[m] != ~slack[m]]
            if not on.size:
                continue
            sign = np.where(slack[on], 1.0, -1.0)
            dd = e._end_difference(dq, e.dofs[on])
            pull = (sign * k[on] * (gap[on] + np.einsum("ij,ij->i", n[on], dd)))[:, None] * n[on]
            ld = local[e.dofs[on]]
            np.add.at(grad, ld[ld >= 0], np.concatenate([-pull, pull], axis=1)[ld >= 0])
            blocks.append((sign * k[on])[:, None, None] * (n[on][:, :, None] * n[on][:, None, :]))
            block_dofs.append(ld)
        H = A_loc
        if blocks:
            vals = two_node_blocks(np.concatenate(blocks))
            ld = np.concatenate(block_dofs)
            ii = np.repeat(ld, 6, axis=1).ravel()  # row-major 6 x 6 blocks over the members' end DOFs
            jj = np.tile(ld, (1, 6)).ravel()
            keep = (ii >= 0) & (jj >= 0)
            H = H + sp.csr_matrix((vals[keep], (ii[keep], jj[keep])), shape=A_loc.shape)
        try:
            delta = CholeskyFactor(H).solve(-grad)
        except SingularMatrixError:
            break
        if not np.all(np.isfinite(delta)):
            break
        p[rows] += delta
        dq[patch_dofs] = p[rows]
        changed = False
        for i, (e, (n, gap, k, slack), m) in enumerate(zip(ropes, geo, members)):
            new = taut_after(e, n, gap, m)
            changed |= not np.array_equal(new, state[i][m])
            state[i][m] = new
        if not changed:
            break
    return result(p)


def energy_change(system, q0: np.ndarray, q1: np.ndarray, lam: float = 1.0) -> float:
    """``Pi(q1) - Pi(q0)`` summed effect by effect, without the cancellation of two totals.

    The total potential is dominated by the work of the weight, so the
    difference of two totals loses the small changes a converging relaxation
    makes. Axial members give their change member by member
    (:meth:`~shellform.effects.axial.AxialBar.energy_change`); constant
    forces contribute ``-f . (q1 - q0)``; other effects the difference of
    their energies.
    """
    total = 0.0
    for e in system.effects:
        factor = lam if e.scales_with_load else 1.0
        if e.is_external and hasattr(e, "force"):
            total -= factor * float(e.force @ (q1 - q0))
        elif hasattr(e, "energy_change"):
            total += factor * e.energy_change(q0, q1)
        else:
            total += factor * (e.energy(q1) - e.energy(q0))
    return total


#: sufficient decrease of the line search: the potential falls by at least this share of the slope
ARMIJO = 1e-4


def _sufficient_decrease(dE1, d1, slope) -> bool:
    """Whether the line search takes the full step as it is.

    ``dE1`` and ``d1`` are the change of potential at the full step and its slope there.
    """
    return dE1 <= ARMIJO * slope or (d1 <= 0.0 and dE1 < 0.0)


def _line_search(at, slope, rnorm0, tiny, max_eval=12, first=None):
    """Step length along a direction ``p`` for the convex potential ``phi(a) = Pi(q + a p)``.

    ``at(a)`` returns ``(phi(a) - phi(0), r(q + a p), r(q + a p) . p)``. The
    full step is taken when it lowers the potential enough (Armijo) or, at
    round-off level (``tiny``), lowers the residual. Otherwise the minimiser of
    ``phi`` on ``(0, 1)`` is located by regula falsi on ``phi'(a) = r(q + a p) . p``
    (increasing, since ``phi`` is convex). Returns ``(alpha, phi(alpha) - phi(0), r)``;
    alpha 0 means no decrease was found. ``first`` is ``at(1.0)`` when the
    caller has evaluated it already.
    """
    dE1, r1, d1 = at(1.0) if first is None else first
    if np.isfinite(dE1) and np.all(np.isfinite(r1)):
        if _sufficient_decrease(dE1, d1, slope):
            return 1.0, dE1, r1
        if tiny and float(np.linalg.norm(r1)) < rnorm0:
            return 1.0, dE1, r1
    # bracket [lo, hi] with phi'(lo) < 0 < phi'(hi)
    lo, dlo = 0.0, slope
    hi, dhi = 1.0, d1 if np.isfinite(d1) else np.inf
    best = (0.0, 0.0, None)
    for _ in range(max_eval):
        # at round-off level phi' need not grow along the step: bisect where the secant has no root
        if np.isfinite(dhi) and dhi > dlo:
            a = hi - dhi * (hi - lo) / (dhi - dlo)
            a = min(max(a, lo + 0.05 * (hi - lo)), hi - 0.05 * (hi - lo))
        else:
            a = 0.5 * (lo + hi)
        dEa, ra, da = at(a)
        if not (np.isfinite(dEa) and np.isfinite(da)):
            hi, dhi = a, np.inf
            continue
        if dEa < best[1]:
            best = (a, dEa, ra)
        if abs(da) <= 0.1 * abs(slope) and dEa < 0.0:
            return a, dEa, ra
        if da < 0:
            lo, dlo = a, da
        else:
            hi, dhi = a, da
    if best[0] > 0 and best[1] <= ARMIJO * best[0] * slope:
        return best
    return 0.0, 0.0, None


def _diagonal_positions(A: sp.csr_matrix) -> np.ndarray:
    """Index into ``A.data`` of every diagonal entry (all present by construction)."""
    n = A.shape[0]
    rows = np.repeat(np.arange(n), np.diff(A.indptr))
    pos = np.flatnonzero(rows == A.indices)
    if pos.size != n:
        raise ModelError("relaxation: the tangent pattern lacks diagonal entries")
    return pos
