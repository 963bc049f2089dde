"""Pseudo-time steps on patches of the net, the rest held: front sweeps and step repair.

Late in a relaxation the out-of-balance force sits at a few nodes, and a step
of the whole net moves a slack front by about one node; a step of the whole
net is also often cut for the sake of a few ropes swung sideways. Both are
local, so both are mended on the patch of nodes around them
(:class:`~.patch.Patch`), with the same pseudo-time step and line search as
the whole net's, on the whole net's potential.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from ..linear import CholeskyFactor, SingularMatrixError
from .bounds import nodal_norms
from .line_search import ARMIJO, line_search
from .patch import NodeGraph, Patch
from .ropes import model_excess


@dataclass(frozen=True)
class PatchContext:
    """What the patch steps of one stiffness stage share.

    Attributes
    ----------
    system : System
        The stage's net.
    graph : NodeGraph
        Its node graph, which finds the patches.
    m : ndarray
        The masses of the free DOFs.
    damping : float
        Mass-proportional damping of the pseudo-time steps [1/s].
    f_ext : ndarray (n_dof,)
        The applied forces at the load factor of the analysis.
    e_floor : float
        Changes of the potential below this are round-off.
    ropes : list
        The tension-only members whose excess over a step's model a repair looks at.
    """

    system: object
    graph: NodeGraph
    m: np.ndarray
    damping: float
    f_ext: np.ndarray
    e_floor: float
    ropes: list = field(default_factory=list)


#: a front sweep runs while the nodes above FRONT_LEVEL times the largest nodal
#: acceleration are at most FRONT_SHARE of the free nodes ...
FRONT_LEVEL = 0.3
FRONT_SHARE = 0.01
#: ... on the nodes within FRONT_RINGS members of them, at most FRONT_STEPS times per step
FRONT_RINGS = 4
FRONT_STEPS = 3


def sweep_fronts(ctx: PatchContext, q, r, h, a_tol) -> int:
    """Newton steps on the patches around the few nodes that hold a relaxation back.

    Late in a relaxation the out-of-balance force sits at a few nodes along
    the fronts between taut and slack regions, and a step of the whole net
    moves such a front by about one node. While the nodes above
    ``FRONT_LEVEL`` times the largest acceleration are few (at most
    ``FRONT_SHARE`` of the free nodes), this takes a pseudo-time step of the
    same form as the global one, ``(M/h^2 + C/h + K) dq = -r``, on the nodes
    within ``FRONT_RINGS`` members of them (:class:`~.patch.Patch`,
    the rest of the net held), with the same line search on the whole net's
    potential, so every accepted step lowers it. A step after which the
    largest acceleration has not fallen is undone and ends the sweep: its
    patch has set up ropes that the next step of the whole net would have to
    undo. ``q`` and ``r`` (free DOFs) are updated in place, ``r`` exactly
    from the patch's members. Returns the number of steps kept.
    """
    system, graph = ctx.system, ctx.graph
    free_index = graph.free_index
    steps = 0
    undo = None
    a_last = np.inf
    for _ in range(FRONT_STEPS + 1):
        acc = nodal_norms(system, r / ctx.m)
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
        patch = Patch(system, graph, graph.within(hot, FRONT_RINGS), ctx.f_ext)
        if not patch.n_moving:
            break
        moving = patch.dofs[patch.moving]
        ql = q[patch.dofs]
        step = patch_step(patch, ctx.m[free_index[moving]], ql, h, ctx.damping, ctx.e_floor)
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


def patch_step(patch, m, ql, h, damping, e_floor):
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

    alpha, dE, _ = line_search(at, slope, float(np.linalg.norm(rl)), tiny)
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


def repair_full_step(ctx: PatchContext, q, p, r1, dE1, slope, h):
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
    (:func:`~.ropes.model_excess`) takes pseudo-time
    steps from it, the rest of the net held. It stops once the potential
    has fallen by the line search's sufficient decrease and the patch's
    largest acceleration is no larger than the largest outside it: a patch
    left far from balance holds the next step of the whole net back.

    Returns ``(q, r, dE, excess)`` -- the state, its residual (free DOFs),
    the change of potential from ``q`` and the repaired ropes' excess -- or
    None when the excess is not local or the patch does not make up for it.
    """
    system, graph, ropes = ctx.system, ctx.graph, ctx.ropes
    free = system.free
    dq = np.zeros(system.n_dof)
    dq[free] = p
    excess = np.concatenate([model_excess(e, q, dq) for e in ropes])
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
    patch = Patch(system, graph, graph.within(np.unique(conn[worst]), REPAIR_RINGS), ctx.f_ext)
    if not 0 < patch.n_moving <= REPAIR_PATCH * free.size:
        return None
    q1 = q.copy()
    q1[free] += p
    ql0 = q1[patch.dofs]
    ql = ql0
    inside = graph.free_index[patch.dofs[patch.moving]]
    m = ctx.m[inside]
    outside = np.ones(free.size, dtype=bool)
    outside[inside] = False
    a_out = float(np.max(np.abs(r1[outside]) / ctx.m[outside], initial=0.0))
    dE = dE1
    for _ in range(REPAIR_STEPS):
        step = patch_step(patch, m, ql, h, ctx.damping, ctx.e_floor)
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

