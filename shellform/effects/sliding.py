"""Sliding supports on tilted planes and lines: a stiff spring across the plane or line.

Curves (arches, rings) are :mod:`~shellform.effects.curve_sliding`.

A node held along some coordinate axes and free along the others is a
support of its own (fixed DOFs). A node that slides on a plane or along a
line of any direction is held by the energy

    E = 1/2 K (x - x_0)^T P (x - x_0),

``P`` the projector onto the directions it may not move in (``n n^T`` for a
plane of unit normal ``n``, ``I - d d^T`` for a line of unit direction ``d``)
and ``x_0`` the node's reference position, on the plane or line. ``K`` is a
multiple of the stiffest member at the node (as the penalty joints of rods
are): the node leaves its plane or line by its reaction over ``K``, about
the member's own elongation divided by the multiple. The effect's force is
the support's reaction.
"""

from __future__ import annotations

import numpy as np

from .base import Effect, element_pattern, scatter


class SlidingSupports(Effect):
    """Stiff springs that keep nodes on their planes or lines.

    Parameters
    ----------
    n_dof : int
    nodes : array_like (k,)
    projectors : array_like (k, 3, 3)
        Projector onto the held directions of every node.
    x0 : array_like (k, 3)
        Reference position of every node.
    stiffness : array_like (k,)
        Spring stiffness ``K`` [N/m].
    """

    name = "sliding"
    #: its force is a support's reaction (:meth:`~shellform.assembly.System.reactions`)
    is_support = True

    def __init__(self, n_dof: int, nodes, projectors, x0, stiffness):
        super().__init__(n_dof)
        self.nodes = np.asarray(nodes, dtype=np.int64)
        self.P = np.asarray(projectors, dtype=float).reshape(-1, 3, 3)
        self.x0 = np.asarray(x0, dtype=float).reshape(-1, 3)
        self.k = np.asarray(stiffness, dtype=float).reshape(-1)
        self.dofs = 3 * self.nodes[:, None] + np.arange(3)
        self._pattern = element_pattern(self.dofs)
        self._values = (self.k[:, None, None] * self.P).ravel()

    def scaled(self, factor: float) -> "SlidingSupports":
        """The same supports with ``factor`` times the springs' stiffness."""
        return SlidingSupports(self.n_dof, self.nodes, self.P, self.x0, factor * self.k)

    def _forces(self, q):
        return self.k[:, None] * np.einsum("nij,nj->ni", self.P, q[self.dofs] - self.x0)

    def energy(self, q):
        return 0.5 * float(np.sum(np.einsum("ni,ni->n", self._forces(q), q[self.dofs] - self.x0)))

    def gradient(self, q):
        return scatter(self.n_dof, self.dofs, self._forces(q))

    def force_magnitudes(self, q):
        return scatter(self.n_dof, self.dofs, np.abs(self._forces(q)))

    def hessian_pattern(self):
        return self._pattern

    def hessian_values(self, q):
        return self._values

    def member_results(self, q):
        d = q[self.dofs] - self.x0
        off = np.sqrt(np.maximum(np.einsum("ni,nij,nj->n", d, self.P, d), 0.0))  # P >= 0, up to rounding
        return {"offset": off, "reaction": self.k * off}


def stiffest_member(structure, nodes) -> np.ndarray:
    """The stiffest member ``EA / L`` at each of ``nodes``: what a support's spring is a multiple of."""
    from ..errors import ModelError

    stiff = np.zeros(structure.n_nodes)
    for g in structure.groups:
        np.maximum.at(stiff, g.connectivity.ravel(), np.repeat(g.EA / g.rest_length, 2))
    lonely = nodes[stiff[nodes] == 0]
    if lonely.size:
        raise ModelError(f"sliding support: node {int(lonely[0])} has no member, so no stiffness to hold it on its "
                         "plane, line or curve by")
    return stiff[nodes]


def sliding_effects(structure) -> list[Effect]:
    """The structure's sliding supports: those on planes and lines as one effect (first, if any), then one
    per curve (:func:`~shellform.effects.curve_sliding.curve_sliding_effects`); each spring its ratio times
    the stiffest member ``EA / L`` at its node, or the stiffness given."""
    from .curve_sliding import curve_sliding_effects

    return plane_and_line_effects(structure) + curve_sliding_effects(structure)


def plane_and_line_effects(structure) -> list[SlidingSupports]:
    """The supports sliding on planes and lines as one effect (none without)."""
    if not structure.sliders:
        return []
    k = np.concatenate([s.stiffness if s.stiffness is not None
                        else s.stiffness_ratio * stiffest_member(structure, s.nodes) for s in structure.sliders])
    nodes = np.concatenate([s.nodes for s in structure.sliders])
    P = np.concatenate([np.broadcast_to(s.held, (len(s.nodes), 3, 3)) for s in structure.sliders])
    x0 = np.concatenate([structure.nodes[s.nodes] if s.origin is None else s.origin for s in structure.sliders])
    return [SlidingSupports(structure.n_dof, nodes, P, x0, k)]
