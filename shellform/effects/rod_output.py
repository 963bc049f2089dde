"""From hinges to rod edges: how rod results reach the line cells of an output file.

Bending and twist live at the hinges (the interior nodes of a rod), a file's
cells are the rod edges. The value on an edge is the mean of the values at the
hinges at its two ends (one at a rod's end edge), which is the linear
interpolation to the edge's midpoint. Bending components are taken, at each
hinge, in the material frame of the edge itself, so the two values averaged
are in the same frame. With a section shape, :class:`EdgeSections` gives the
extreme-fibre stress of every edge from its axial force and moments.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..geometry.sections import extreme_fibre_stress


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


@dataclass(frozen=True)
class EdgeSections:
    """What the extreme-fibre stress of every rod edge needs; NaN on edges of rods without a section shape.

    Attributes
    ----------
    area, inv_modulus_1, inv_modulus_2 : ndarray (m,)
        ``A`` [m^2] and ``c1 / I1``, ``c2 / I2`` [1/m^3].
    round : ndarray of bool (m,)
        A circular outline (bending stresses add as a vector).
    EA, rest_length : ndarray (m,)
        For the axial force ``N = EA (l / l_bar - 1)``, the law of
        :class:`~shellform.effects.rod_stretch.RodStretching`.
    """

    area: np.ndarray
    inv_modulus_1: np.ndarray
    inv_modulus_2: np.ndarray
    round: np.ndarray
    EA: np.ndarray
    rest_length: np.ndarray

    def max_stress(self, length: np.ndarray, M1: np.ndarray, M2: np.ndarray) -> np.ndarray:
        """Largest ``|N / A + M1 y1 / I1 + M2 y2 / I2|`` over each edge's section [Pa]."""
        N = self.EA * (length / self.rest_length - 1.0)
        return extreme_fibre_stress(N, M1, M2, self.area, self.inv_modulus_1, self.inv_modulus_2, self.round)
