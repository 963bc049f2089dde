"""Planar grids of rods: the starting footprint of buckling-induced gridshells."""

from __future__ import annotations

import numpy as np

from ..errors import ModelError


def square_grid_polylines(n: int, span: float, edges_per_cell: int, z: float = 0.0) -> list[np.ndarray]:
    """``n`` rods along x and ``n`` along y over a square of side ``span``.

    The rods sit at ``span (i + 1) / (n + 1)``, i = 0..n-1, and run the full
    span; each has ``(n + 1) edges_per_cell`` equal edges, so every crossing
    falls on a node of both rods (ready for shared nodes or penalty joints,
    see :func:`~shellform.rods.polylines.stack_polylines`).

    Returns
    -------
    list of ndarray (N, 3)
        The x-rods first, then the y-rods.
    """
    if int(n) < 1 or int(edges_per_cell) < 1 or not (np.isfinite(span) and span > 0):
        raise ModelError(f"square grid: need n >= 1, edges_per_cell >= 1 and span > 0, got {n}, {edges_per_cell}, {span}")
    n, k = int(n), int(edges_per_cell)
    s = np.linspace(0.0, span, (n + 1) * k + 1)
    c = span * np.arange(1, n + 1) / (n + 1)
    zz = np.full_like(s, z)
    return [np.stack([s, np.full_like(s, ci), zz], axis=1) for ci in c] + [
        np.stack([np.full_like(s, ci), s, zz], axis=1) for ci in c
    ]
