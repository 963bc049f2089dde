"""Polylines as rods: points of several polylines in one node array, and resampling in arc length."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from ..errors import ModelError
from ..geometry.selection import coincident_groups


def stack_polylines(polylines: Sequence[np.ndarray], merge: bool = False, tol: float = 1e-9):
    """Put the points of several polylines into one node array.

    Parameters
    ----------
    polylines : sequence of (N_k, 3) arrays
    merge : bool
        Give coincident points of different polylines a single shared node
        (exact joints). Otherwise every polyline keeps its own nodes and the
        coincident pairs are returned for penalty joints.
    tol : float
        Distance below which points coincide, relative to the size of the
        point cloud.

    Returns
    -------
    nodes : ndarray (n, 3)
    indices : list of ndarray
        Node indices of each polyline.
    pairs : ndarray (k, 2)
        Coincident nodes of different polylines (empty when ``merge``).
    """
    from scipy.spatial import cKDTree

    pts = [np.asarray(p, dtype=float) for p in polylines]
    for k, p in enumerate(pts):
        if p.ndim != 2 or p.shape[1] != 3 or len(p) < 2:
            raise ModelError(f"polyline {k}: expected an array of shape (N, 3) with N >= 2, got {p.shape}")
        if not np.all(np.isfinite(p)):
            raise ModelError(f"polyline {k}: coordinates must be finite")
    allp = np.concatenate(pts)
    owner = np.concatenate([np.full(len(p), k) for k, p in enumerate(pts)])
    scale = max(float(np.ptp(allp, axis=0).max()), 1e-300)
    pairs = np.array(sorted(cKDTree(allp).query_pairs(tol * scale)), dtype=np.int64).reshape(-1, 2)
    pairs = pairs[owner[pairs[:, 0]] != owner[pairs[:, 1]]]
    offsets = np.concatenate([[0], np.cumsum([len(p) for p in pts])])
    if not merge:
        return allp, [np.arange(offsets[k], offsets[k + 1]) for k in range(len(pts))], pairs
    first, index = coincident_groups(len(allp), pairs)
    nodes = allp[first]
    return nodes, [index[offsets[k] : offsets[k + 1]] for k in range(len(pts))], np.zeros((0, 2), dtype=np.int64)


def resample_polyline(points: np.ndarray, n_edges: int) -> np.ndarray:
    """``n_edges + 1`` points equally spaced in arc length along a polyline."""
    p = np.asarray(points, dtype=float)
    seg = np.linalg.norm(np.diff(p, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    if s[-1] <= 0:
        raise ModelError("resample_polyline: the polyline has zero length")
    target = np.linspace(0.0, s[-1], int(n_edges) + 1)
    return np.stack([np.interp(target, s, p[:, k]) for k in range(3)], axis=1)
