"""The fixed sparsity pattern of a tangent: CSR structure from COO triplets, and the slot of every triplet.

A :class:`~shellform.assembly.System` computes its patterns once; each
assembly then only sums values into the CSR data of the pattern.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp


def same_pattern(a: tuple[np.ndarray, np.ndarray], b: tuple[np.ndarray, np.ndarray]) -> bool:
    """Whether two Hessian patterns list the same entries in the same order."""
    return all(x is y or np.array_equal(x, y) for x, y in zip(a, b))


def stable_order(key: np.ndarray, n_keys: int) -> np.ndarray:
    """The stable permutation that sorts the integers ``key`` (``0 <= key < n_keys``): a counting sort.

    The conversion of a COO matrix with one column per entry to CSR sorts by
    row (``key``) in linear time, and within a row the canonical column order
    is the entries' order.
    """
    m = key.size
    index = np.int32 if max(m, n_keys) < 2**31 - 1 else np.int64
    M = sp.coo_matrix((np.ones(m, dtype=np.int8), (key.astype(index, copy=False), np.arange(m, dtype=index))),
                      shape=(n_keys, max(m, 1))).tocsr()
    if not M.has_sorted_indices:
        M.sort_indices()
    return M.indices.astype(np.int64, copy=False)


class Pattern:
    """CSR pattern of a set of COO triplets, with the map from triplet to CSR slot.

    Two counting sorts (by column, then stably by row) order the triplets;
    duplicates are then neighbours. On a net of 10^5 nodes (7.2 million
    triplets) this takes a fraction of a comparison sort of the entries'
    keys (``benchmarks/bench_assembly.py --setup``).

    Attributes
    ----------
    slot : ndarray (triplets,) or None
        CSR slot of every triplet.
    indices, indptr : ndarray
        The CSR structure.
    nnz : int
    shape : tuple
    rows : ndarray (nnz,) or None
        Row of each stored entry (kept until :meth:`restricted` has used it).
    """

    def __init__(self, rows: np.ndarray, cols: np.ndarray, shape: tuple[int, int]):
        n_rows, n_cols = shape
        order = stable_order(cols, n_cols)
        order = order[stable_order(rows[order], n_rows)]
        r, c = rows[order], cols[order]
        first = np.ones(order.size, dtype=bool)
        first[1:] = (r[1:] != r[:-1]) | (c[1:] != c[:-1])
        self.slot = np.empty(order.size, dtype=np.int64)
        self.slot[order] = np.cumsum(first) - 1
        self._set(c[first], np.bincount(r[first], minlength=n_rows), shape)
        self.rows = r[first]

    def _set(self, indices, row_counts, shape) -> None:
        self.indices = indices.astype(np.int32)
        self.indptr = np.concatenate([[0], np.cumsum(row_counts)]).astype(np.int32)
        self.nnz = int(self.indices.size)
        self.shape = shape

    def restricted(self, index: np.ndarray) -> tuple[Pattern, np.ndarray]:
        """The pattern of the entries in rows and columns that ``index`` keeps (renumbered by it, -1 for a
        dropped one, in the same order), and the slot there of every triplet of this pattern.

        A triplet of a dropped row or column gets the slot one past the end (a
        bin that is cut off), so that values scatter without being masked.
        """
        entry_rows, entry_cols = index[self.rows], index[self.indices]
        kept = (entry_rows >= 0) & (entry_cols >= 0)
        n = int(index.max()) + 1
        sub = Pattern.__new__(Pattern)
        sub._set(entry_cols[kept], np.bincount(entry_rows[kept], minlength=n), (n, n))
        sub.slot = sub.rows = None
        to_sub = np.full(self.nnz, sub.nnz, dtype=np.int64)
        to_sub[kept] = np.arange(sub.nnz)
        return sub, to_sub[self.slot]

    def matrix(self, vals: np.ndarray) -> sp.csr_matrix:
        data = np.bincount(self.slot, weights=vals, minlength=self.nnz)
        return sp.csr_matrix((data, self.indices, self.indptr), shape=self.shape)
