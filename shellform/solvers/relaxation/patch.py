"""The potential of a rope net on a patch of nodes, every other node held.

A relaxation of a large net ends with a few nodes out of balance along the
fronts between its taut and slack regions; a front moves by about one node per
step of the whole net (docs/theory-mra.md). A Newton step on the nodes around
such a front, with the rest of the net held where it is, moves it at the cost
of a small factorisation. :class:`Patch` is that local problem: the members
with an end on the patch, renumbered so that their evaluation, assembly and
factorisation cost nothing that grows with the net. :class:`NodeGraph` finds
the patch, the nodes within a few members of some seed nodes.

Only nets whose internal energy is all in axial members (ropes, bars) and
whose loads are constant forces have such a patch (:func:`patchable`).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ...sparse_pattern import Pattern
from .ropes import is_axial


def patchable(system) -> bool:
    """Whether every internal effect of ``system`` is made of axial members and every load is constant."""
    return any(is_axial(e) for e in system.effects) and all(
        is_axial(e) or (e.is_external and not e.hessian_pattern()[0].size) for e in system.effects)


class NodeGraph:
    """Which nodes and members touch which, for the axial members of a System.

    The incidences do not depend on the state or on the members' stiffness, so
    one graph serves every stiffness stage of a relaxation.

    Attributes
    ----------
    free_index : ndarray (n_dof,)
        Position of each DOF among the System's free DOFs, -1 where constrained.
    n_free_nodes : int
        Nodes with at least one free DOF.
    """

    def __init__(self, system):
        self.n_nodes = system.n_dof // 3
        self.free_index = np.full(system.n_dof, -1, dtype=np.int64)
        self.free_index[system.free] = np.arange(system.free.size)
        self.n_free_nodes = int(np.count_nonzero(np.bincount(system.free // 3, minlength=self.n_nodes)))
        axial = [e for e in system.effects if is_axial(e)]
        conn = np.concatenate([e.conn for e in axial])
        a, b = conn[:, 0], conn[:, 1]
        n = self.n_nodes
        adj = sp.csr_matrix((np.ones(2 * len(a)), (np.concatenate([a, b]), np.concatenate([b, a]))), shape=(n, n))
        self._adj = (adj.indptr, adj.indices)
        # node -> (effect, member) incidences, one CSR per effect
        self._members = []
        for e in axial:
            m = len(e.conn)
            inc = sp.csr_matrix((np.ones(2 * m), (e.conn.ravel(), np.repeat(np.arange(m), 2))), shape=(n, m))
            self._members.append((inc.indptr, inc.indices))

    def within(self, seeds: np.ndarray, rings: int) -> np.ndarray:
        """Nodes at most ``rings`` members away from the ``seeds`` (node indices), sorted."""
        return within_rings(*self._adj, seeds, rings)

    def members_of(self, nodes: np.ndarray) -> list[np.ndarray]:
        """For each axial effect, the members with at least one end among ``nodes``."""
        return [np.unique(_gather(indptr, indices, nodes)) for indptr, indices in self._members]


def within_rings(indptr: np.ndarray, indices: np.ndarray, seeds: np.ndarray, rings: int) -> np.ndarray:
    """Vertices at most ``rings`` edges from ``seeds`` in the graph of a CSR adjacency, sorted.

    Only the growing front's rows are read, so the cost follows the region, not the graph.
    """
    reached = np.zeros(indptr.size - 1, dtype=bool)
    front = np.unique(np.asarray(seeds, dtype=np.int64))
    reached[front] = True
    for _ in range(rings):
        nb = _gather(indptr, indices, front)
        front = np.unique(nb[~reached[nb]])
        if not front.size:
            break
        reached[front] = True
    return np.flatnonzero(reached)


def _gather(indptr: np.ndarray, indices: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """Concatenated column indices of some CSR rows, without a loop over rows."""
    start, stop = indptr[rows], indptr[rows + 1]
    count = stop - start
    total = int(count.sum())
    if total == 0:
        return np.zeros(0, dtype=np.int64)
    # position k of the output reads indices[start[row of k] + (k - first output of that row)]
    offset = np.repeat(start - np.concatenate([[0], np.cumsum(count)[:-1]]), count)
    return indices[offset + np.arange(total)].astype(np.int64)


class Patch:
    """The potential as a function of the free DOFs of ``nodes``, all other DOFs held.

    Parameters
    ----------
    system : System
        A net whose effects pass :func:`patchable`.
    graph : NodeGraph
        Built from ``system`` (or from a System with the same members).
    nodes : ndarray of int
        The nodes that move.
    f_ext : ndarray (n_dof,)
        The applied forces at the load factor of the analysis.

    Attributes
    ----------
    dofs : ndarray
        Global DOFs of the local numbering: the patch's nodes and the held
        nodes at the far end of their members.
    moving : ndarray
        Local indices of the DOFs that move (free DOFs of ``nodes``).
    """

    def __init__(self, system, graph: NodeGraph, nodes: np.ndarray, f_ext: np.ndarray):
        axial = [e for e in system.effects if is_axial(e)]
        members = graph.members_of(nodes)
        ends = np.unique(np.concatenate([e.conn[m].ravel() for e, m in zip(axial, members)] + [nodes]))
        index = np.full(graph.n_nodes, -1, dtype=np.int64)
        index[ends] = np.arange(ends.size)
        n_dof = 3 * ends.size
        self.effects = [e.on_members(m, index, n_dof) for e, m in zip(axial, members)]
        self.dofs = (3 * ends[:, None] + np.arange(3)).ravel()
        self.moving = np.flatnonzero(np.repeat(np.isin(ends, nodes), 3) & (graph.free_index[self.dofs] >= 0))
        self.f_ext = f_ext[self.dofs]
        # the tangent on the moving DOFs, with the diagonal always present
        local = np.full(n_dof, -1, dtype=np.int64)
        local[self.moving] = np.arange(self.moving.size)
        rows = np.concatenate([local[e.hessian_pattern()[0]] for e in self.effects] + [np.arange(self.moving.size)])
        cols = np.concatenate([local[e.hessian_pattern()[1]] for e in self.effects] + [np.arange(self.moving.size)])
        self._keep = (rows >= 0) & (cols >= 0)
        self._pattern = Pattern(rows[self._keep], cols[self._keep], (self.moving.size,) * 2)

    @property
    def n_moving(self) -> int:
        return self.moving.size

    def internal_force(self, q_local: np.ndarray) -> np.ndarray:
        """Forces of the patch's members on every local DOF (the held ones only in part)."""
        return sum(e.gradient(q_local) for e in self.effects)

    def residual(self, q_local: np.ndarray) -> np.ndarray:
        """Out-of-balance force at the moving DOFs (complete: every member of a moving node is here)."""
        return (self.internal_force(q_local) - self.f_ext)[self.moving]

    def tangent(self, q_local: np.ndarray) -> sp.csr_matrix:
        """Hessian of the potential over the moving DOFs."""
        vals = np.concatenate([e.hessian_values(q_local) for e in self.effects] + [np.zeros(self.moving.size)])
        return self._pattern.matrix(vals[self._keep])

    def energy_change(self, q0: np.ndarray, q1: np.ndarray) -> float:
        """Change of the whole net's potential between two local states (the held DOFs equal)."""
        return sum(e.energy_change(q0, q1) for e in self.effects) - float(self.f_ext @ (q1 - q0))
