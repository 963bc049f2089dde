"""Cross-sections of rods by shape: area, second moments, torsion constant and extreme fibres.

A section lies in the plane of the material directors ``m1, m2`` of its rod
edge; ``y1, y2`` are the coordinates along them. The bending energy of a rod
(:mod:`shellform.effects.rod_bend`) pairs its material curvature
``omega_1 = kb . m2`` (the centreline turning towards ``m1``) with
``E I1``, ``I1 = integral of y1^2 dA``, and ``omega_2 = -kb . m1`` (turning
towards ``m2``) with ``E I2``, ``I2 = integral of y2^2 dA``. The extreme-fibre
distances ``c1, c2`` are the largest ``|y1|``, ``|y2|`` of the section.

A rectangle's ``depth`` lies along ``m1``, its ``width`` along ``m2``. On a
gridshell whose rods have the surface normal as first director, a lath lying
flat on the surface has its thickness as ``depth``: it bends out of the
surface about its weak axis (``I1 = width depth^3 / 12``).

The torsion constant of a rectangle is Saint-Venant's series (Timoshenko and
Goodier, *Theory of Elasticity*, 3rd ed., 1970, section 109), for sides
``a >= b``:

    J = a b^3 / 3 [1 - (192 / pi^5) (b / a) sum_{n = 1, 3, 5, ...} tanh(n pi a / (2 b)) / n^5],

summed over its first 200 terms (the rest is below 1e-10 of the sum).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ModelError


def _positive(shape: str, **values) -> None:
    for what, v in values.items():
        if not np.isfinite(v) or v <= 0:
            raise ModelError(f"{shape} section: {what} must be positive and finite, got {v}")


@dataclass(frozen=True)
class SectionShape:
    """Geometric properties of a cross-section (all computed from its dimensions).

    Attributes
    ----------
    area : float
        ``A`` [m^2].
    I1, I2 : float
        Second moments of area ``integral y1^2 dA``, ``integral y2^2 dA`` [m^4].
    J : float
        Saint-Venant torsion constant [m^4].
    c1, c2 : float
        Extreme-fibre distances along ``m1``, ``m2`` [m].
    round : bool
        The outline is a circle: the largest bending stress is
        ``c |M| / I`` over the resultant moment, not the sum over the axes.
    """

    area: float
    I1: float
    I2: float
    J: float
    c1: float
    c2: float
    round: bool

    @property
    def polar_moment(self) -> float:
        """``I1 + I2`` [m^4]: with the density, the mass moment of inertia per length about the axis."""
        return self.I1 + self.I2

    def max_stress(self, N, M1, M2):
        """Largest ``|sigma|`` of the normal stress ``N / A + M1 y1 / I1 + M2 y2 / I2`` over the section [Pa].

        For a rectangle the largest value sits at a corner, ``|N| / A +
        |M1| c1 / I1 + |M2| c2 / I2``; for a circle (hollow or solid) on the
        outer circle, ``|N| / A + c |M| / I``. Shear stresses are not included.
        """
        return extreme_fibre_stress(N, M1, M2, self.area, self.c1 / self.I1, self.c2 / self.I2, self.round)


def extreme_fibre_stress(N, M1, M2, area, s1, s2, round):
    """Largest ``|sigma|`` over a section, element-wise: ``|N| / A`` plus the bending part.

    ``s1 = c1 / I1`` and ``s2 = c2 / I2`` are the section moduli's inverses;
    the bending part is ``|M1| s1 + |M2| s2`` (a rectangle's corner) or, where
    ``round``, ``hypot(M1 s1, M2 s2)`` (the outer circle, ``c1 = c2``, ``I1 = I2``).
    """
    N, M1, M2 = (np.asarray(v, dtype=float) for v in (N, M1, M2))
    b1, b2 = M1 * s1, M2 * s2
    bending = np.where(round, np.hypot(b1, b2), np.abs(b1) + np.abs(b2))
    return np.abs(N) / area + bending


def solid_circle(radius: float) -> SectionShape:
    """Solid circle: ``A = pi r^2``, ``I1 = I2 = pi r^4 / 4``, ``J = pi r^4 / 2``."""
    _positive("solid circle", radius=radius)
    I = np.pi * radius**4 / 4
    return SectionShape(area=np.pi * radius**2, I1=I, I2=I, J=np.pi * radius**4 / 2, c1=radius, c2=radius,
                        round=True)


def hollow_circle(outer_radius: float, thickness: float) -> SectionShape:
    """Circular tube: ``A = pi (ro^2 - ri^2)``, ``I = pi (ro^4 - ri^4) / 4``, ``J = 2 I``."""
    _positive("hollow circle", outer_radius=outer_radius, thickness=thickness)
    if thickness >= outer_radius:
        raise ModelError(f"hollow circle section: thickness {thickness} must be less than the outer radius "
                         f"{outer_radius} (a solid circle is 'circle')")
    ri = outer_radius - thickness
    I = np.pi * (outer_radius**4 - ri**4) / 4
    return SectionShape(area=np.pi * (outer_radius**2 - ri**2), I1=I, I2=I, J=2 * I, c1=outer_radius,
                        c2=outer_radius, round=True)


def rectangle_torsion_constant(a: float, b: float) -> float:
    """Saint-Venant torsion constant of an ``a`` by ``b`` rectangle (series of Timoshenko and Goodier, section 109)."""
    _positive("rectangle", a=a, b=b)
    a, b = max(a, b), min(a, b)
    n = np.arange(1, 400, 2, dtype=float)
    series = np.sum(np.tanh(n * np.pi * a / (2 * b)) / n**5)
    return a * b**3 / 3 * (1 - 192 / np.pi**5 * (b / a) * series)


def rectangle(depth: float, width: float) -> SectionShape:
    """Rectangle of ``depth`` along ``m1`` and ``width`` along ``m2``.

    ``I1 = width depth^3 / 12``, ``I2 = depth width^3 / 12``,
    ``J`` from :func:`rectangle_torsion_constant`, corners at
    ``(+-depth / 2, +-width / 2)``.
    """
    _positive("rectangle", depth=depth, width=width)
    return SectionShape(area=depth * width, I1=width * depth**3 / 12, I2=depth * width**3 / 12,
                        J=rectangle_torsion_constant(depth, width), c1=depth / 2, c2=width / 2, round=False)
