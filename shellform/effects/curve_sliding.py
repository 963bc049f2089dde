"""Supports that slide along curves (an arch, a ring beam): a stiff spring to the nearest point of the curve.

A node ``x`` that slides along the curve ``c`` is held by the energy

    E = 1/2 K |r|^2,    r = x - s - c(t*),    c'(t*) . r = 0,

``t*`` the parameter of the curve's point nearest to ``x - s``, and ``s`` a
shift of the curve per node (zero, or the small offset that makes the curve
pass through the node's reference position, as a plane or a line of
:mod:`~shellform.effects.sliding` passes through it). Because ``r`` is normal
to the curve, the force is ``K r`` whatever ``t*`` does (its change does not
change ``E`` to first order), and differentiating ``c'(t*) . r = 0`` gives

    dt*/dx = c'^T / (c' . c' - c'' . r),
    H = K (I - c' c'^T / (c' . c' - c'' . r)),

the distance's own curvature: on the convex side of an arch the spring is a
little stiff along the curve, on the concave side a little soft. At an end of
an open curve the nearest point is the end itself and ``H = K I``. ``K`` is
a multiple of the stiffest member at the node, as for planes and lines; the
effect's force is the support's reaction.
"""

from __future__ import annotations

import numpy as np

from ..geometry.space_curve import SpaceCurve
from .base import Effect, element_pattern, scatter


class CurveSupports(Effect):
    """Stiff springs that keep nodes on one curve.

    Parameters
    ----------
    n_dof : int
    nodes : array_like (k,)
    curve : SpaceCurve
    shift : array_like (k, 3)
        The curve's shift for every node.
    stiffness : array_like (k,)
        Spring stiffness ``K`` [N/m].
    """

    name = "curve_sliding"
    #: its force is a support's reaction (:meth:`~shellform.assembly.System.reactions`)
    is_support = True

    def __init__(self, n_dof: int, nodes, curve: SpaceCurve, shift, stiffness):
        super().__init__(n_dof)
        self.nodes = np.asarray(nodes, dtype=np.int64)
        self.curve = curve
        # the curve as arrays, which a checkpoint's fingerprint of the effect takes in (it skips other objects)
        self.curve_knots, self.curve_coefficients = curve.spline.t, curve.spline.c
        self.shift = np.asarray(shift, dtype=float).reshape(-1, 3)
        self.k = np.asarray(stiffness, dtype=float).reshape(-1)
        self.dofs = 3 * self.nodes[:, None] + np.arange(3)
        self._pattern = element_pattern(self.dofs)

    def scaled(self, factor: float) -> "CurveSupports":
        """The same supports with ``factor`` times the springs' stiffness."""
        return CurveSupports(self.n_dof, self.nodes, self.curve, self.shift, factor * self.k)

    def nearest(self, q):
        """Parameter of each node's nearest point, whether it is an end, and the offset ``r`` from it."""
        p = q[self.dofs] - self.shift
        t, end = self.curve.nearest(p)
        return t, end, p - self.curve(t)

    def energy(self, q):
        r = self.nearest(q)[2]
        return 0.5 * float(np.sum(self.k * np.einsum("ni,ni->n", r, r)))

    def gradient(self, q):
        return scatter(self.n_dof, self.dofs, self.k[:, None] * self.nearest(q)[2])

    def force_magnitudes(self, q):
        return scatter(self.n_dof, self.dofs, np.abs(self.k[:, None] * self.nearest(q)[2]))

    def hessian_pattern(self):
        return self._pattern

    def hessian_values(self, q):
        t, end, r = self.nearest(q)
        c1, c2 = self.curve(t, 1), self.curve(t, 2)
        den = np.einsum("ni,ni->n", c1, c1) - np.einsum("ni,ni->n", c2, r)
        # beyond the centre of curvature the nearest point is no minimum along the curve: count it as an end
        along = np.where(end | (den <= 0.0), 0.0, 1.0 / np.where(den > 0.0, den, 1.0))
        H = np.eye(3)[None] - along[:, None, None] * c1[:, :, None] * c1[:, None, :]
        return (self.k[:, None, None] * H).ravel()

    def member_results(self, q):
        t, _, r = self.nearest(q)
        off = np.linalg.norm(r, axis=1)
        return {"offset": off, "reaction": self.k * off, "curve_parameter": t}


def curve_sliding_effects(structure) -> list[CurveSupports]:
    """One effect per curve the structure's nodes slide along, each spring its ratio times the stiffest
    member ``EA / L`` at its node (or the stiffness given)."""
    from .sliding import stiffest_member

    effects = []
    for s in structure.curve_sliders:
        k = s.stiffness if s.stiffness is not None else s.stiffness_ratio * stiffest_member(structure, s.nodes)
        shift = np.zeros((len(s.nodes), 3)) if s.shift is None else s.shift
        effects.append(CurveSupports(structure.n_dof, s.nodes, s.curve, shift, k))
    return effects
