"""Node sets chosen by where the nodes are: nearest to points, inside a box, on a polyline."""

from __future__ import annotations

import numpy as np

from ..errors import ModelError


def _points(points, what: str) -> np.ndarray:
    p = np.asarray(points, dtype=float)
    if p.ndim == 1:
        p = p[None, :]
    if p.ndim != 2 or p.shape[1] != 3 or not np.all(np.isfinite(p)):
        raise ModelError(f"{what}: expected finite [x, y, z] points, got shape {p.shape}")
    return p


def nearest_nodes(nodes: np.ndarray, points) -> np.ndarray:
    """The node nearest to each point (one node per point, in the points' order)."""
    p = _points(points, "nearest nodes")
    from scipy.spatial import cKDTree

    return cKDTree(nodes).query(p)[1].astype(np.int64)


def nodes_in_box(nodes: np.ndarray, box) -> np.ndarray:
    """Nodes inside the axis-aligned box ``[[x0, y0, z0], [x1, y1, z1]]`` (bounds included), sorted."""
    b = _points(box, "box")
    if b.shape != (2, 3):
        raise ModelError(f"box: expected two corners [[x0, y0, z0], [x1, y1, z1]], got {len(b)} points")
    lo, hi = b.min(axis=0), b.max(axis=0)
    return np.flatnonzero(np.all((nodes >= lo) & (nodes <= hi), axis=1))


def nodes_on_polyline(nodes: np.ndarray, polyline, tolerance: float) -> np.ndarray:
    """Nodes within ``tolerance`` of a polyline (its segments between consecutive points), sorted."""
    p = _points(polyline, "curve")
    if len(p) < 2:
        raise ModelError(f"curve: a polyline needs at least 2 points, got {len(p)}")
    if not tolerance >= 0:
        raise ModelError(f"curve: tolerance must be >= 0, got {tolerance!r}")
    best = np.full(len(nodes), np.inf)
    for a, b in zip(p[:-1], p[1:]):
        d = b - a
        t = np.clip((nodes - a) @ d / max(float(d @ d), 1e-300), 0.0, 1.0)
        best = np.minimum(best, np.linalg.norm(nodes - (a + t[:, None] * d), axis=1))
    return np.flatnonzero(best <= tolerance)


def coincident_groups(n: int, pairs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Points joined by ``pairs`` (and pairs of pairs) as groups numbered in order of first appearance.

    Returns the index of each group's first point (ascending) and the group
    of every one of the ``n`` points.
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    pairs = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    _, label = connected_components(graph, directed=False)
    _, first = np.unique(label, return_index=True)
    order = np.argsort(first)
    new = np.empty(len(order), dtype=np.int64)
    new[order] = np.arange(len(order))
    return np.sort(first), new[label]
