"""Where the rods of a network cross, and the chord of each rod there: the stencils of joint rotation springs."""

from __future__ import annotations

import numpy as np


def crossing_chords(network) -> np.ndarray:
    """Per crossing of two rods, the nodes ``(a_u, b_u, a_v, b_v)`` of their chords there.

    A crossing is a node that two rods pass (shared-node joints), or the two
    nodes of a penalty joint. A rod's chord at a node runs from its neighbour
    before to its neighbour after (around a closed rod's seam too), or from
    the node itself at a rod's end. Where more than two rods meet at a node,
    each rod is paired with the next one through it.
    """
    node, a, b, rod = [], [], [], []
    for r in network.rods:
        n = r.nodes
        prev = np.roll(n, 1) if r.closed else np.concatenate([n[:1], n[:-1]])
        nxt = np.roll(n, -1) if r.closed else np.concatenate([n[1:], n[-1:]])
        node.append(n)
        a.append(prev)
        b.append(nxt)
        rod.append(np.full(len(n), r.index))
    if not node:
        return np.zeros((0, 4), dtype=np.int64)
    node, a, b, rod = (np.concatenate(v) for v in (node, a, b, rod))
    # a penalty joint's copy counts as the node it stands for
    pairs = network.joints
    where = node.copy()
    if len(pairs):
        owner = np.arange(int(max(node.max(), pairs.max())) + 1)
        owner[pairs[:, 1]] = pairs[:, 0]
        where = owner[node]
    order = np.lexsort((rod, where))
    where, a, b, rod = where[order], a[order], b[order], rod[order]
    # consecutive entries at one place, of different rods
    same = (where[1:] == where[:-1]) & (rod[1:] != rod[:-1])
    i = np.flatnonzero(same)
    return np.column_stack([a[i], b[i], a[i + 1], b[i + 1]]).astype(np.int64)
