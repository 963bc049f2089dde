"""From hinges to rod edges: how rod results reach the line cells of an output file.

Bending and twist live at the hinges (the interior nodes of a rod), a file's
cells are the rod edges. The value on an edge is the mean of the values at the
hinges at its two ends (one at a rod's end edge), which is the linear
interpolation to the edge's midpoint. Bending components are taken, at each
hinge, in the material frame of the edge itself, so the two values averaged
are in the same frame.
"""

from __future__ import annotations

import numpy as np


def edge_means(per_side: np.ndarray, hinge_edges: np.ndarray, n_edges: int) -> np.ndarray:
    """Mean over the hinge sides that touch each edge; NaN on an edge no hinge touches.

    Parameters
    ----------
    per_side : ndarray (h, 2) or (h, 2, k)
        Value at every hinge as seen from its edge before (``[:, 0]``) and
        after (``[:, 1]``).
    hinge_edges : ndarray (h, 2)
        The two edges of every hinge.
    n_edges : int
    """
    per_side = np.asarray(per_side, dtype=float)
    edges = hinge_edges.ravel()
    count = np.bincount(edges, minlength=n_edges).astype(float)
    flat = per_side.reshape(edges.size, -1)
    sums = np.stack([np.bincount(edges, flat[:, c], minlength=n_edges) for c in range(flat.shape[1])], axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = sums / count[:, None]
    return mean.reshape((n_edges,) + per_side.shape[2:])
