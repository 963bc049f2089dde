"""What a rod is made of and how it rests: the options of :meth:`RodNetwork.add_rod`.

:class:`RodSection` holds the stiffness and inertia per unit length,
:class:`RestShape` the shape in which the rod carries no stress;
:func:`section_of` gives the section of a shape (:mod:`shellform.geometry.sections`)
in a material, :func:`circular_section` that of a solid circular rod.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from ..errors import ModelError
from ..geometry.sections import SectionShape, solid_circle


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
        Bending and torsional stiffness [N m^2] per interior node. ``EI``
        is the stiffness ``E I1`` of the material curvature ``omega_1``
        (the rod turning towards ``m1``).
    mass_per_length : float
        [kg/m], lumped to the nodes (self-weight and dynamics).
    rotational_inertia : float
        Mass moment of inertia about the axis per unit length [kg m]
        (``rho (I1 + I2)``), lumped to the twist DOFs for dynamics.
    EI2 : float or (n_hinges,), optional
        Stiffness ``E I2`` of the curvature ``omega_2`` (turning towards
        ``m2``); default ``EI`` (an isotropic section).
    shape : SectionShape, optional
        The section's geometry; with it the rod's results include the
        extreme-fibre stress ``max_stress``.
    """

    EA: ArrayLike
    EI: ArrayLike
    GJ: ArrayLike
    mass_per_length: float = 0.0
    rotational_inertia: float = 0.0
    EI2: ArrayLike | None = None
    shape: SectionShape | None = None


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
    director : array_like (3,) or (n_edges, 3), optional
        One vector: the first material director of the first edge (projected
        perpendicular to it), the frames of the other edges following by
        space-parallel transport; default: vertical projected, or x for
        vertical edges. One vector per edge (projected perpendicular to each
        edge): the section's orientation along the rod, for example the
        surface normal of a gridshell.
    """

    natural_curvature: str | ArrayLike = "rest"
    natural_twist: ArrayLike = 0.0
    rest_length: ArrayLike | None = None
    director: ArrayLike | None = None


def section_of(shape: SectionShape, E: float, G: float, density: float = 0.0) -> RodSection:
    """Stiffness and inertia per unit length of a section ``shape`` in a material ``(E, G, density)``.

    ``EA = E A``, ``EI = E I1``, ``EI2 = E I2``, ``GJ = G J``, mass per
    length ``rho A``, rotational inertia per length ``rho (I1 + I2)``.
    """
    for what, v in (("E", E), ("G", G)):
        if not np.isfinite(v) or v <= 0:
            raise ModelError(f"section: {what} must be positive and finite, got {v}")
    if not np.isfinite(density) or density < 0:
        raise ModelError(f"section: density must be non-negative, got {density}")
    return RodSection(EA=E * shape.area, EI=E * shape.I1, GJ=G * shape.J, mass_per_length=density * shape.area,
                      rotational_inertia=density * shape.polar_moment, EI2=E * shape.I2, shape=shape)


def circular_section(E: float, G: float, radius: float, density: float = 0.0) -> RodSection:
    """Stiffness and inertia per unit length of a solid circular rod.

    ``A = pi r^2``, ``I = pi r^4 / 4``, ``J = pi r^4 / 2`` (as in the gridshell
    paper).
    """
    return section_of(solid_circle(radius), E, G, density)
