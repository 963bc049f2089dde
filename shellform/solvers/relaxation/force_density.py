"""The start of the implicit scheme: the force-density shape of the net.

With one force density in every axial member, nodal equilibrium is linear in
the node positions: one scalar graph-Laplacian solve gives a hanging shape,
from which the relaxation starts instead of letting the net fall from its
planform.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from ...errors import ModelError
from .ropes import axial_effects


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
    n_members = sum(len(e.L) for e in axial_effects(system))
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
    axial = axial_effects(system)
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

