"""Masses, reference scales, tolerances and the explicit stability bound of a relaxation."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...errors import ModelError
from .options import RelaxationOptions
from .ropes import is_axial, member_lengths

#: stability limit of classical RK4 on the imaginary axis is 2*sqrt(2); of leapfrog, 2
_RK4_LIMIT = 2.8
_LEAPFROG_LIMIT = 2.0

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


def free_node_mask(system) -> np.ndarray:
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
        if is_axial(e):
            length = member_lengths(e, q)
            k = (e.EA / e.L) * np.maximum(1.0, (e.L - length) / np.maximum(length, 1e-300))
            S += 2.0 * (np.bincount(e.conn[:, 0], k, minlength=n) + np.bincount(e.conn[:, 1], k, minlength=n))
        else:
            rows, _ = e.hessian_pattern()
            if len(rows) == 0:
                continue
            row_sum = np.bincount(rows, np.abs(e.hessian_values(q)), minlength=system.n_dof)
            S += 2.0 * row_sum[: 3 * n].reshape(n, 3).max(axis=1)
    return S


def nodal_norms(system, x_free: np.ndarray) -> np.ndarray:
    """Euclidean norm at every node of a free-DOF vector (zero at held nodes)."""
    full = np.zeros(system.n_dof)
    full[system.free] = x_free
    full = full.reshape(-1, 3)
    return np.sqrt(np.einsum("ij,ij->i", full, full))


def nodal_max(system, x_free: np.ndarray) -> float:
    """Largest Euclidean norm over nodes of a free-DOF vector."""
    return float(nodal_norms(system, x_free).max())


@dataclass
class Setup:
    """The state a relaxation starts from, its masses, reference scales and tolerances."""

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


def start_velocity(system, v0) -> np.ndarray:
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


def setup(system, q0, options: RelaxationOptions, v0=None) -> Setup:
    """The masses, scales and tolerances of a relaxation of ``system`` from ``q0``, checked."""
    lam, mu, rtol = options.lam, options.mu, options.rtol
    v_tol, a_tol, damping = options.velocity_tol, options.acceleration_tol, options.damping
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
    m_node = nodal_masses(system, options.extra_mass)
    zero = np.flatnonzero(free_node_mask(system) & (m_node <= 0))
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
    fn_mask = free_node_mask(system)
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
    return Setup(q, m_node, m, g_ref, L_ref, v_tol, a_tol, damping, a_tol_asked, start_velocity(system, v0))


def stable_time_step(system, q=None, extra_mass=None, scheme: str = "rk4", damping: float = 0.0) -> float:
    """Explicit time step allowed by the stiffness bound, with a 10 % margin.

    ``omega_max^2 <= max_i S_i / m_i`` (:func:`node_stiffness_bound`); the step is
    ``0.9 * 2.8 / omega`` for RK4 (whose stability region reaches 2.83 on the
    imaginary axis, with ``omega`` raised to ``hypot(omega, damping)`` for the
    damped eigenvalues) and ``0.9 * 2 / omega`` for leapfrog.
    """
    q = system.q_ref if q is None else q
    return bound_step(system, q, nodal_masses(system, extra_mass), scheme, damping)


def bound_step(system, q, m_node, scheme, damping):
    S = node_stiffness_bound(system, q)
    free_nodes = free_node_mask(system) & (S > 0)
    if not np.any(free_nodes):
        raise ModelError("relaxation: no free node is attached to a member; nothing holds the net")
    omega = float(np.sqrt(np.max(S[free_nodes] / np.maximum(m_node[free_nodes], 1e-300))))
    if scheme == "rk4":
        return 0.9 * _RK4_LIMIT / float(np.hypot(omega, damping))
    return 0.9 * _LEAPFROG_LIMIT / omega

