"""What the relaxation knows of ropes, from the rope effect's public arrays.

The axial effects (:class:`~shellform.effects.axial.AxialBar`,
:class:`~shellform.effects.axial.Rope`) give their energy, gradient and
Hessian; a relaxation step also needs the ropes' piecewise model: which
slack ropes a step stretches, the springs of engaged slack ropes, and how the
energy along a step differs from the step's model. Those are computed here
from the members' connectivity ``conn``, end DOFs ``dofs``, stiffness ``EA``
and rest length ``L`` (one row per member).

A rope's linear model at ``q`` is ``(n, gap, k, slack)``: unit direction from
the first end node to the second, length minus rest length, axial stiffness
``EA / L`` and the mask of the slack ropes (not longer than their rest
length). A step ``dd`` of the end-node difference changes a rope's length by
``n . dd`` to first order.
"""

from __future__ import annotations

import numpy as np

from ...effects.axial import AxialBar, Rope, two_node_blocks
from ...effects.base import scatter


def is_axial(effect) -> bool:
    """Whether ``effect`` is made of two-node axial members (bars, rod stretching, ropes)."""
    return isinstance(effect, (AxialBar, Rope))


def axial_effects(system) -> list:
    """The System's effects made of axial members."""
    return [e for e in system.effects if is_axial(e)]


def rope_effects(system) -> list:
    """The System's tension-only ropes: the members whose slack state a step's model follows."""
    return [e for e in system.effects if isinstance(e, Rope)]


def end_difference(e, v: np.ndarray, dofs: np.ndarray | None = None) -> np.ndarray:
    """Second end minus first end of a DOF vector ``v``, per member (of ``dofs``, default all)."""
    dofs = e.dofs if dofs is None else dofs
    return v[dofs[:, 3:]] - v[dofs[:, :3]]


def member_lengths(e, q: np.ndarray) -> np.ndarray:
    """Current length of every member."""
    d = end_difference(e, q)
    return np.sqrt(np.einsum("ij,ij->i", d, d))


def is_slack(e, q: np.ndarray) -> np.ndarray:
    """Mask of the ropes not longer than their rest length at ``q``."""
    return ~(member_lengths(e, q) > e.L)


def linearised(e, q: np.ndarray):
    """The ropes' axial model ``(n, gap, k, slack)`` at ``q`` (module docstring)."""
    d = end_difference(e, q)
    length = np.sqrt(np.einsum("ij,ij->i", d, d))
    return d / length[:, None], length - e.L, e.EA / e.L, ~(length > e.L)


def stretched_by(e, q: np.ndarray, dq: np.ndarray, model=None) -> np.ndarray:
    """Slack ropes that the straight step ``dq`` stretches in the linearised model.

    A slack rope has no stiffness, so a Newton step does not see it; when
    the step lengthens it past its rest length to first order
    (``l + n . (dq_b - dq_a) > L``), the rope would resist it. ``model``
    is ``linearised(e, q)`` when the caller has it already.
    """
    n, gap, _, slack = linearised(e, q) if model is None else model
    dd = end_difference(e, dq)
    return slack & (gap + np.einsum("ij,ij->i", n, dd) > 0)


def model_excess(e, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
    """Each rope's change of energy along the step ``dq`` less that of the step's model of it.

    The model is the one a relaxation step is solved with: a taut rope's
    second-order expansion at ``q`` (its pull and its Hessian, axial and
    geometric stiffness), a slack rope that the step stretches to first
    order its spring ``1/2 (EA / L) (l - L + n . dd)^2``
    (:func:`engaged_terms`), any other slack rope nothing. A positive
    value is energy the model did not foresee.
    """
    n, gap, k, slack = linearised(e, q)
    dd = end_difference(e, dq)
    nd = np.einsum("ij,ij->i", n, dd)
    tension = k * gap
    geometric = tension / (gap + e.L)
    taylor = tension * nd + 0.5 * ((k - geometric) * nd**2 + geometric * np.einsum("ij,ij->i", dd, dd))
    spring = 0.5 * k * np.maximum(gap + nd, 0.0) ** 2
    return e.member_energy_changes(q, q + dq) - np.where(slack, spring, taylor)


def switch_model_change(e, q: np.ndarray, dq: np.ndarray, model=None) -> np.ndarray:
    """Each rope's change of energy in the step's piecewise model less that in its Taylor model.

    The Taylor model at ``q`` (the tangent and the pull) gives a taut rope
    its axial spring whichever way the step moves it, and a slack rope
    nothing. The piecewise model gives every rope the spring
    ``1/2 (EA / L) (l - L + n . dd)_+^2`` and a taut rope its geometric
    stiffness as well: the convex model that a relaxation step is solved
    in once its slack ropes are engaged and settled. The two differ only
    for ropes that the step switches: ``+1/2 k x^2`` for a slack rope it
    stretches to ``x = l - L + n . dd > 0``, ``-1/2 k x^2`` for a taut
    rope it shortens to ``x < 0``. ``model`` is ``linearised(e, q)`` when
    the caller has it already.
    """
    n, gap, k, slack = linearised(e, q) if model is None else model
    dd = end_difference(e, dq)
    x = gap + np.einsum("ij,ij->i", n, dd)
    return 0.5 * k * np.where(slack, np.maximum(x, 0.0) ** 2, -np.minimum(x, 0.0) ** 2)


def engaged_terms(e, q: np.ndarray, engaged: np.ndarray):
    """Gradient and Hessian values of slack ropes modelled as taut springs.

    Each rope of the mask ``engaged`` contributes ``1/2 (EA / L) (l + n . dd - L)^2``
    for a step ``dd`` of its end-node difference: the rope's own energy
    once the step has made it taut, linearised in its length. It carries no
    tension at ``q``, so it has no geometric stiffness. Returns the
    gradient over all DOFs at ``dd = 0`` and Hessian values in the order of
    the effect's ``hessian_pattern()`` (zero for the other ropes).
    """
    members = np.flatnonzero(engaged)
    f, blocks = engaged_blocks(e, q, members)
    grad = scatter(e.n_dof, e.dofs[members], f)
    vals = np.zeros((len(e.L), 36))
    vals[members] = blocks.reshape(-1, 36)
    return grad, vals.ravel()


def engaged_blocks(e, q: np.ndarray, members: np.ndarray):
    """:func:`engaged_terms` of the ropes ``members`` only, at a cost that follows their number.

    Returns ``(f, values)``: the forces on the members' six end-node DOFs,
    shape (m, 6) (to scatter at ``e.dofs[members]``), and their Hessian
    values at the effect's ``hessian_entries(members)``.
    """
    d = end_difference(e, q, e.dofs[members])
    length = np.sqrt(np.einsum("ij,ij->i", d, d))
    n = d / length[:, None]
    k = e.EA[members] / e.L[members]
    f = (k * (length - e.L[members]))[:, None] * n
    K = k[:, None, None] * (n[:, :, None] * n[:, None, :])
    return np.concatenate([-f, f], axis=1), two_node_blocks(K)
