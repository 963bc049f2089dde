"""What a rod is made of and how it rests: the options of :meth:`RodNetwork.add_rod`.

:class:`RodSection` holds the stiffness and inertia per unit length,
:class:`RestShape` the shape in which the rod carries no stress;
:func:`circular_section` gives the section of a solid circular rod.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from ..errors import ModelError


@dataclass(frozen=True)
class RodSection:
    """Stiffness and inertia per unit length of a rod.

    Values are checked when the rod is added (:meth:`RodNetwork.add_rod`),
    where the number of edges and hinges is known.

    Attributes
    ----------
    EA : float or (n_edges,)
        Axial stiffness [N] per edge.
    EI, GJ : float or (n_hinges,)
        Bending and torsional stiffness [N m^2] per interior node.
    mass_per_length : float
        [kg/m], lumped to the nodes (self-weight and dynamics).
    rotational_inertia : float
        Mass moment of inertia about the axis per unit length [kg m]
        (``rho J``), lumped to the twist DOFs for dynamics.
    """

    EA: ArrayLike
    EI: ArrayLike
    GJ: ArrayLike
    mass_per_length: float = 0.0
    rotational_inertia: float = 0.0


@dataclass(frozen=True)
class RestShape:
    """The shape in which a rod carries no stress, and the frame its curvature is given in.

    Attributes
    ----------
    natural_curvature : {"rest", "straight"} or array (n_hinges, 2)
        ``"rest"``: the reference geometry is stress free.
        ``"straight"``: the rod is straight when unstressed.
        An array gives the natural material curvature [1/m] at each
        interior node (components along ``m1``, ``m2`` of the frames
        built from ``director``).
    natural_twist : float or (n_hinges,)
        Natural twist rate [rad/m] on top of the twist-free rest frames.
    rest_length : float or (n_edges,), optional
        Unstressed edge lengths; default: the reference edge lengths.
    director : array_like (3,), optional
        First material director of the first edge (projected perpendicular
        to it); default: vertical projected, or x for vertical edges.
        The frames of the other edges follow by space-parallel transport.
    """

    natural_curvature: str | ArrayLike = "rest"
    natural_twist: ArrayLike = 0.0
    rest_length: ArrayLike | None = None
    director: ArrayLike | None = None


def circular_section(E: float, G: float, radius: float, density: float = 0.0) -> RodSection:
    """Stiffness and inertia per unit length of a solid circular rod.

    ``A = pi r^2``, ``I = pi r^4 / 4``, ``J = pi r^4 / 2`` (as in the gridshell
    paper).
    """
    for what, v in (("E", E), ("G", G), ("radius", radius)):
        if not np.isfinite(v) or v <= 0:
            raise ModelError(f"circular section: {what} must be positive and finite, got {v}")
    if not np.isfinite(density) or density < 0:
        raise ModelError(f"circular section: density must be non-negative, got {density}")
    A = np.pi * radius**2
    I = np.pi * radius**4 / 4
    J = np.pi * radius**4 / 2
    return RodSection(EA=E * A, EI=E * I, GJ=G * J, mass_per_length=density * A, rotational_inertia=density * J)
