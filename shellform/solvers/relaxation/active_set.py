"""The slack ropes in a step's model: an active set, settled on patches.

A slack rope has no stiffness, so the tangent's step does not see it; a step
that pulls one taut overshoots. :func:`engage_slack_ropes` solves the step
again with the slack ropes it stretches modelled as taut springs (a
primal-dual active-set iteration on the ropes' piecewise quadratic model);
:func:`settle_slack_set` settles the ropes whose state the step still gets
wrong by semismooth Newton on the patch of nodes around them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ...effects.axial import two_node_blocks
from ...effects.base import scatter
from ..linear import CholeskyFactor, SingularMatrixError
from .linalg import with_values
from .patch import NodeGraph
from .ropes import end_difference, engaged_blocks, linearised, stretched_by


@dataclass(frozen=True)
class SlackRopeModel:
    """The ropes whose slack state a step's model follows, and how far :func:`engage_slack_ropes` goes.

    Attributes
    ----------
    system : System
    ropes : list
        The System's tension-only rope effects.
    graph : NodeGraph, optional
        The net's node graph: with it, the step is settled on the patches around
        the ropes whose state it still gets wrong (:func:`settle_slack_set`).
    rounds : int
        Solves after the first one that update the set of engaged ropes.
    """

    system: object
    ropes: list
    graph: NodeGraph | None = None
    rounds: int = 2


def engage_slack_ropes(model: SlackRopeModel, solver, A, r, q, eta, engaged=None):
    """The pseudo-time step with the slack ropes it would stretch modelled as taut springs.

    The step's model treats a slack rope as absent, so a step that pulls one
    taut overshoots (the rope's energy ``1/2 (EA / L) (l - L)^2`` appears at
    once) and the line search cuts it. This is a primal-dual active-set
    iteration on the piecewise quadratic model instead: the slack ropes that
    the step lengthens past their rest length to first order join the model
    (:func:`~.ropes.engaged_terms`), the step is solved
    again, and the set is updated until it stops changing or after
    ``model.rounds`` more solves. ``engaged`` (a mask per rope effect, e.g. the
    previous step's final set) is where the set starts; ropes taut by now
    leave it. With the model's ``graph``, the step is then settled on the nodes around
    the ropes whose state it still gets wrong (:func:`settle_slack_set`):
    slack ropes when the rounds end with a set that still changes, and taut
    ropes that the step shortens below their rest length, which the rounds
    do not model. Returns the step and its final set (None when empty).
    """
    system, ropes, graph = model.system, model.ropes, model.graph
    free = system.free
    dq = np.zeros(system.n_dof)
    # the ropes' linear model at q serves every round and the settling: q does not change here
    geo = [linearised(e, q) for e in ropes]
    if engaged is not None:
        engaged = [m & slack for m, (n, gap, k, slack) in zip(engaged, geo)]
        if not any(m.any() for m in engaged):
            engaged = None
    p = None
    settled = False
    for _ in range(model.rounds + 1):
        used = engaged
        if engaged is None:
            p = solver.solve(A, -r, eta)
        else:
            A_set, g = with_engaged(system, ropes, engaged, A, q)
            p = solver.solve(A_set, -(r + g[free]), eta)
        dq[free] = p
        masks = [stretched_by(e, q, dq, model) for e, model in zip(ropes, geo)]
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
    return settle_slack_set(ropes, graph, A, r, q, p, used, geo)


def with_engaged(system, ropes, engaged, A, q):
    """``A`` plus the springs of the ``engaged`` slack ropes, and their pulls (all DOFs).

    Only the engaged ropes are evaluated and added, at their positions in the
    tangent's fixed pattern: they are few, and a whole-net assembly of their
    terms (mostly zeros) cost 1.2 s per round at 10^6 nodes.
    """
    g = np.zeros(system.n_dof)
    out = with_values(A, A.data.copy())
    for e, m in zip(ropes, engaged):
        members = np.flatnonzero(m)
        f, vals = engaged_blocks(e, q, members)
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


def settle_slack_set(ropes, graph, A, r, q, p, used, geo=None):
    """Settle the slack set of a step on the nodes around the ropes whose state it gets wrong.

    ``p`` was solved with every taut rope and the slack ropes of ``used``
    modelled as springs (:func:`engage_slack_ropes`). It may stretch other
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
    change there. ``geo`` is the ropes' :func:`~.ropes.linearised` at ``q``, when the caller
    has it. Returns the step and the set of the slack ropes it stretches
    (None when empty).
    """
    free_index = graph.free_index
    dq = np.zeros(free_index.size)
    dq[free_index >= 0] = p
    geo = [linearised(e, q) for e in ropes] if geo is None else geo

    def taut_after(e, n, gap, members):
        dd = end_difference(e, dq, e.dofs[members])
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
        grad, H = _patch_model(ropes, geo, members, state, dq, local, A_rows @ p + r[rows], A_loc)
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


def _patch_model(ropes, geo, members, state, dq, local, grad, A_loc):
    """Gradient and Hessian on a patch of the step's model with the ropes in the ``state`` given.

    ``A_loc`` holds every rope taut at ``q`` as a spring, so a stretched slack
    rope adds one and a released taut rope takes its spring away; ``grad`` is
    ``A p + r`` on the patch's rows (updated in place), ``local`` the patch
    row of every DOF (-1 off the patch).
    """
    blocks, block_dofs = [], []
    for e, (n, gap, k, slack), m, s in zip(ropes, geo, members, state):
        on = m[s[m] != ~slack[m]]
        if not on.size:
            continue
        sign = np.where(slack[on], 1.0, -1.0)
        dd = end_difference(e, dq, e.dofs[on])
        pull = (sign * k[on] * (gap[on] + np.einsum("ij,ij->i", n[on], dd)))[:, None] * n[on]
        ld = local[e.dofs[on]]
        np.add.at(grad, ld[ld >= 0], np.concatenate([-pull, pull], axis=1)[ld >= 0])
        blocks.append((sign * k[on])[:, None, None] * (n[on][:, :, None] * n[on][:, None, :]))
        block_dofs.append(ld)
    if not blocks:
        return grad, A_loc
    vals = two_node_blocks(np.concatenate(blocks))
    ld = np.concatenate(block_dofs)
    ii = np.repeat(ld, 6, axis=1).ravel()  # row-major 6 x 6 blocks over the members' end DOFs
    jj = np.tile(ld, (1, 6)).ravel()
    keep = (ii >= 0) & (jj >= 0)
    return grad, A_loc + sp.csr_matrix((vals[keep], (ii[keep], jj[keep])), shape=A_loc.shape)
