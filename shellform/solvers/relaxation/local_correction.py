"""A kept factorisation corrected where the matrix has changed since it was made.

Between two steps of a relaxation the tangent changes in two ways: a little
everywhere (the net moves, the tensions settle) and a lot in a few places
(ropes that go slack or are pulled taut gain or lose their axial stiffness,
``EA / L``, against a transverse stiffness ``N / l`` smaller by the inverse
rope strain). Conjugate gradients preconditioned by the old factor handle the
first kind in a few iterations, but every rope of the second kind adds an
outlying eigenvalue, and at 10^5 nodes hundreds of ropes change state per
step. :class:`LocalCorrection` adds an exact solve on the nodes around those
entries to the old factor, as a symmetric multiplicative Schwarz
preconditioner of two parts (the nodes that changed, the whole net with the
old factor): the outliers are then taken out by the local solve, whose size
follows the slack fronts, not the net.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import scipy.sparse as sp

from ..linear import CholeskyFactor, SingularMatrixError
from .patch import within_rings

#: an entry has changed when it moved by more than this share of the geometric mean of its two diagonal entries
CHANGE = 0.3
#: the exact solve covers the changed nodes and this many rings of neighbours around them ...
RINGS = 3
#: ... as long as that is at most this share of the nodes; beyond it a new factorisation is due
MOST_SHARE = 0.25
#: entries compared at a time
CHUNK = 1 << 22


class LocalCorrection:
    """The changed region of a matrix with a fixed pattern, and its corrected preconditioner.

    Parameters
    ----------
    A : scipy.sparse.csr_matrix
        Any matrix of the pattern (sorted indices, every diagonal entry stored).
    node_of : ndarray of int, shape (n,)
        The node of every row, numbered from 0 (a node's DOFs share it).
    """

    def __init__(self, A: sp.csr_matrix, node_of: np.ndarray):
        self.indptr = A.indptr.copy()
        self.indices = A.indices.copy()
        # int32 where it fits: these arrays are as long as the pattern (6e7 entries at 10^6 nodes)
        index = np.int32 if A.nnz < 2**31 else np.int64
        self.rows = np.repeat(np.arange(A.shape[0], dtype=index), np.diff(A.indptr))
        self.diag = np.flatnonzero(self.rows == self.indices)
        if self.diag.size != A.shape[0]:
            raise ValueError("local correction: the pattern lacks diagonal entries")
        self.node_of = np.asarray(node_of, dtype=index)
        n_nodes = int(self.node_of.max()) + 1 if self.node_of.size else 0
        # a node's rows share their neighbours, so the first row of each node gives the node graph
        first = np.zeros(A.shape[0], dtype=bool)
        first[np.unique(self.node_of, return_index=True)[1]] = True
        sub = A[first]  # its stored entries, the slack ropes' exact zeros included
        rows, cols = np.repeat(np.arange(sub.shape[0]), np.diff(sub.indptr)), sub.indices
        link = sp.csr_matrix((np.ones(rows.size, dtype=np.int8), (self.node_of[first][rows], self.node_of[cols])),
                             shape=(n_nodes, n_nodes))
        self.graph = (link.indptr, link.indices)
        self.n_nodes = n_nodes

    def fits(self, A: sp.csr_matrix) -> bool:
        """Whether ``A`` has this pattern."""
        return (A.nnz == self.indices.size and np.array_equal(A.indptr, self.indptr)
                and np.array_equal(A.indices, self.indices))

    def changed_nodes(self, data: np.ndarray, kept: np.ndarray) -> np.ndarray:
        """Mask of the nodes with an entry changed from ``kept`` to ``data`` (values in pattern order).

        An entry has changed when it moved by more than :data:`CHANGE` of
        ``sqrt(|a_ii| |a_jj|)`` of the new matrix: a rope pulled taut or gone
        slack changes its blocks by about their whole size, a settling net by
        a small share of them.
        """
        root = np.sqrt(np.abs(data[self.diag]))
        nodes = np.zeros(self.n_nodes, dtype=bool)
        for start in range(0, data.size, CHUNK):  # in pieces: whole-pattern temporaries would cost GBs
            part = slice(start, start + CHUNK)
            rows = self.rows[part]
            changed = np.abs(data[part] - kept[part]) > CHANGE * root[rows] * root[self.indices[part]]
            nodes[self.node_of[rows[changed]]] = True
        return nodes

    def region(self, data: np.ndarray, kept: np.ndarray) -> np.ndarray | None:
        """Rows of the exact solve: the changed nodes and :data:`RINGS` rings around them.

        Returns None when they are more than :data:`MOST_SHARE` of the nodes.
        """
        nodes = np.zeros(self.n_nodes, dtype=bool)
        nodes[within_rings(*self.graph, np.flatnonzero(self.changed_nodes(data, kept)), RINGS)] = True
        if nodes.sum() > MOST_SHARE * self.n_nodes:
            return None
        return np.flatnonzero(nodes[self.node_of])

    def preconditioner(self, A: sp.csr_matrix, kept: np.ndarray,
                       kept_solve: Callable[[np.ndarray], np.ndarray]) -> Callable[[np.ndarray], np.ndarray] | None:
        """``b -> M^-1 b`` for ``A``: the old factor (of the values ``kept``) corrected on the changed rows.

        One application solves on the changed rows, then with the old factor
        on the remaining residual, then on the changed rows again; the
        sequence is symmetric, as conjugate gradients need. Returns the old
        factor's solve alone when nothing changed, and None when the changed
        region is too large (a new factorisation is due) or its block is not
        positive definite.
        """
        rows = self.region(A.data, kept)
        if rows is None:
            return None
        if rows.size == 0:
            return kept_solve
        try:
            local = CholeskyFactor(A[rows][:, rows])
        except SingularMatrixError:
            return None
        cols = A[:, rows]

        def apply(b: np.ndarray) -> np.ndarray:
            x = np.zeros_like(b)
            x[rows] = local.solve(b[rows])
            x += kept_solve(b - cols @ x[rows])
            x[rows] += local.solve((b - A @ x)[rows])
            return x

        return apply
