"""Nested-dissection orders of the unknowns of a net's tangent, from the node coordinates."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp


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


def dof_order(A: sp.csr_matrix, q: np.ndarray, free: np.ndarray) -> np.ndarray:
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

