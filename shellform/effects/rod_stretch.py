"""Stretching of discrete elastic rods (Eq. 1a of the gridshell paper).

``E_s = 1/2 sum_j EA (eps^j)^2 |e_bar^j|`` with ``eps^j = |e^j| / |e_bar^j| - 1``:
the same law as an elastic bar on every rod edge, so the element formulas are
those of :class:`~shellform.effects.axial.AxialBar`; this class only names the
effect and its output for rods.
"""

from __future__ import annotations

from .axial import AxialBar


class RodStretching(AxialBar):
    """Axial stretching of all rod edges at once.

    Parameters
    ----------
    n_dof : int
        Size of the global DOF vector.
    edges : array_like (m, 2)
        End nodes of every rod edge.
    EA : array_like (m,)
        Axial stiffness [N].
    rest_length : array_like (m,)
        Undeformed edge lengths ``|e_bar|`` [m].
    """

    name = "rod_stretch"
    member_kind = "rod"
