"""The tangent from effects that give the upper triangles of their element blocks.

Rod hinges give only the upper triangles of their symmetric 11 x 11 blocks
(:meth:`~shellform.effects.base.Effect.hessian_upper_pattern`): about half the
values to compute. An :class:`UpperTangent` sums them, mirrored, with the full
Hessian values of the other effects into a pattern's CSR data: by one product
with a constant 0/1 matrix, or by the effects' own compiled loop, which adds
their values straight into the data (``upper_scatter`` of their class).

The effects are handed over at every call, never kept: a shallow copy of a
System with copies of its effects (another axial stiffness) assembles from
those.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import scipy.sparse as sp

from .errors import ModelError
from .sparse_pattern import Pattern, same_pattern


class UpperSum(NamedTuple):
    """How the values are summed into one pattern's CSR data (:meth:`UpperTangent.scatter`)."""

    product: sp.csr_matrix  # the 0/1 matrix, by the rows of the data it fills
    rows: np.ndarray | None  # those rows, None for all
    size: int  # the length of the data with its last, dropped slot
    direct: dict  # group index -> function (effects, q, data) that adds the group's values itself


class UpperTangent:
    """The layout of the values of a System's tangent when some effect gives upper triangles.

    One buffer holds a slice per group: the effects with equal upper
    patterns, summed by their class, and the other effects' full Hessian
    values (summed over effects sharing a pattern).

    Parameters
    ----------
    effects : sequence of Effect
    ranges : list of (start, end)
        The slice of the System's triplets that each effect's full Hessian values fill.
    """

    def __init__(self, effects, ranges):
        self.ranges = ranges
        upper = [e.hessian_upper_pattern() for e in effects]
        groups, count = [], 0
        for k in range(len(effects)):
            if upper[k] is not None:
                size = len(upper[k][0])
                kind = "upper"
                shared = next((g for g in groups if g[0] == "upper" and len(upper[g[1][0]][0]) == size
                               and same_pattern(upper[g[1][0]], upper[k])), None)
            else:
                start, end = ranges[k]
                if end == start:
                    continue
                size = end - start
                kind = "full"
                shared = next((g for g in groups if g[0] == "full" and ranges[g[1][0]] == (start, end)), None)
            if shared is not None:
                shared[1].append(k)
            else:
                groups.append([kind, [k], slice(count, count + size)])
                count += size
        self.groups = [(kind, tuple(ks), sl) for kind, ks, sl in groups]
        self.buffer = np.zeros(count)

    @classmethod
    def of(cls, effects, ranges) -> UpperTangent | None:
        """The layout for ``effects``; None when no effect gives upper triangles."""
        if all(e.hessian_upper_pattern() is None for e in effects):
            return None
        return cls(effects, ranges)

    def scatter(self, effects, index: np.ndarray, pattern: Pattern, slot: np.ndarray) -> UpperSum:
        """How the values are summed into the CSR data of ``pattern``.

        A constant 0/1 matrix with one row per entry of the pattern (and an
        empty last row), one column per value of the buffer: a full Hessian
        value sits in the row of its entry (``slot``, by triplet of the full
        patterns), a mirrored upper value in the rows of its entry and of the
        transposed entry; values in a row or column of a DOF that ``index``
        maps to -1 (a constrained DOF, for the free pattern) in none. A group
        whose effects add their values to the data themselves
        (``upper_scatter`` of their class, given the slots of every value and
        of its mirror, the last slot for none) is left out of the matrix.
        """
        n = pattern.shape[0]
        dropped = pattern.nnz  # the last row of S, the last slot of the data: cut off
        keys = pattern.indices.astype(np.int64)
        keys += np.repeat(np.arange(n, dtype=np.int64) * n, np.diff(pattern.indptr))  # ascending (canonical CSR)
        rows, cols = [], []
        direct = {}
        for g, (kind, ks, sl) in enumerate(self.groups):
            e = effects[ks[0]]
            if kind == "upper":
                r, c, mirrored = e.hessian_upper_pattern()
                fr, fc = index[r], index[c]
                keep = (fr >= 0) & (fc >= 0)
                first = np.flatnonzero(keep)
                twice = np.flatnonzero(keep & np.asarray(mirrored, dtype=bool))
                slots = []
                for a, b, sel in ((fr, fc, first), (fc, fr, twice)):
                    key = a[sel] * n + b[sel]
                    pos = np.minimum(np.searchsorted(keys, key), keys.size - 1)
                    if np.any(keys[pos] != key):
                        raise ModelError(f"effect {e.name!r}: its upper Hessian pattern has entries outside its "
                                         f"Hessian pattern")
                    slots.append((pos, sel))
                own = getattr(type(e), "upper_scatter", None)
                if own is not None:
                    at = [np.full(len(r), dropped, dtype=np.int64) for _ in slots]
                    for a, (pos, sel) in zip(at, slots):
                        a[sel] = pos
                    add = own([effects[k] for k in ks], *at)
                    if add is not None:
                        direct[g] = add
                        continue
                for pos, sel in slots:
                    rows.append(pos)
                    cols.append(sl.start + sel)
            else:
                start, end = self.ranges[ks[0]]
                at = slot[start:end]
                sel = np.flatnonzero(at < pattern.nnz)
                rows.append(at[sel])
                cols.append(sl.start + sel)
        rows = np.concatenate(rows) if rows else np.zeros(0, dtype=np.int64)
        cols = np.concatenate(cols) if cols else np.zeros(0, dtype=np.int64)
        S = sp.coo_matrix((np.ones(rows.size), (rows, cols)), shape=(pattern.nnz + 1, self.buffer.size)).tocsr()
        S.sum_duplicates()
        if not direct:
            return UpperSum(S, None, S.shape[0], direct)
        # the product then fills only the rows it has: over all rows it took as long as the stretching values
        filled = np.flatnonzero(np.diff(S.indptr))
        return UpperSum(S[filled], filled, S.shape[0], direct)

    def data(self, effects, q: np.ndarray, scatter: UpperSum) -> np.ndarray:
        """The CSR data at ``q`` from the effects' values, summed as :meth:`scatter` says."""
        buffer = self.buffer
        for g, (kind, ks, sl) in enumerate(self.groups):
            if g in scatter.direct:
                continue
            if kind == "upper":
                group = [effects[k] for k in ks]
                type(group[0]).summed_hessian_upper_values(group, q, out=buffer[sl])
            else:
                buffer[sl] = effects[ks[0]].hessian_values(q)
                for k in ks[1:]:
                    buffer[sl] += effects[k].hessian_values(q)
        if scatter.rows is None:
            data = scatter.product @ buffer
        else:
            data = np.zeros(scatter.size)
            data[scatter.rows] = scatter.product @ buffer
        for g, add in scatter.direct.items():
            add([effects[k] for k in self.groups[g][1]], q, data)
        return data[:-1]
