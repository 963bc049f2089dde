"""When a residual counts as equilibrium.

Converged means the forces balance: the free residual is small against the
forces in play at the state (:meth:`~shellform.assembly.System.forces_in_play`,
the applied loads and the reactions), ``|r| <= rtol * scale + atol``. The
scale never grows with a member's stiffness, so a stiff member cannot hide an
unbalanced load.

A residual is a sum of member forces, each computed from coordinates known to
machine precision only: a member of axial stiffness ``k = EA / L`` rounds its
force to about ``eps k |x|``, and the residual's norm to about
``eps |diag K| max|x|`` (:func:`roundoff_level`). Where that level lies above
the tolerance no iteration can meet it. A residual within the rounding level
is then accepted when its largest entry is still below ``roundoff_rtol``
(default ``1e-4``) of the largest force in play at any DOF (the largest
entries: rounding noise grows with the square root of the model's size while
a local load's forces do not); a residual that stalls near the rounding level
above that is an honest failure that names the achieved residual and the reason: an
exact answer for a model whose members differ in stiffness by ``10^12`` needs
more digits than a double has.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

EPS = float(np.finfo(float).eps)
#: largest residual, relative to the forces in play, accepted where round-off stops the iteration
ROUNDOFF_RTOL = 1e-4
#: a residual that stops falling within this many rounding levels has stalled there
STALL_BAND = 10.0


@dataclass(frozen=True)
class EquilibriumCheck:
    """The equilibrium test of one state.

    Attributes
    ----------
    residual : float
        Norm of the free residual.
    scale : float
        Forces in play: the largest of the norms of the free DOFs' summed
        member and load magnitudes, of the applied loads and of the reactions.
    tolerance : float
        ``rtol * scale + atol``.
    roundoff : float
        Estimated rounding level of the residual (0 when not estimated).
    roundoff_rtol : float
        Largest relative residual accepted at the rounding level.
    applied : float
        Norm of the applied loads (NaN when not known: then they are taken to be present).
    residual_max, scale_max : float
        Largest entry of the residual, and largest force in play at any DOF
        (the largest load or reaction entry where larger).
    """

    residual: float
    scale: float
    tolerance: float
    roundoff: float = 0.0
    roundoff_rtol: float = ROUNDOFF_RTOL
    applied: float = float("nan")
    residual_max: float = float("nan")
    scale_max: float = float("nan")

    @property
    def relative(self) -> float:
        """Largest residual entry relative to the largest force in play."""
        if not self.scale_max > 0:
            return 0.0 if self.residual_max == 0 else float("inf")
        return self.residual_max / self.scale_max

    @property
    def met(self) -> bool:
        """The residual meets the tolerance."""
        return bool(self.residual <= self.tolerance)

    @property
    def converged(self) -> bool:
        """The tolerance is met, or the residual is within the rounding level and small enough.

        Where nothing is loaded and the forces in play are themselves within
        the rounding level (a rigid motion under prescribed displacements), the
        state is force-free as far as doubles can tell, and any residual at that
        level is accepted. Applied loads are never noise: they must be balanced.
        """
        return self.met or (self.residual <= self.roundoff and self.acceptable_at_roundoff)

    @property
    def near_roundoff(self) -> bool:
        """Within a few rounding levels: a residual that stops falling here cannot be pushed lower."""
        return bool(self.residual <= STALL_BAND * self.roundoff)

    @property
    def acceptable_at_roundoff(self) -> bool:
        """Small enough to be accepted where round-off stops the iteration (see :attr:`converged`)."""
        noise = self.applied == 0.0 and self.scale <= self.roundoff
        return bool(noise or self.residual_max <= self.roundoff_rtol * self.scale_max)

    def describe(self) -> str:
        """The residual against its tolerance, in words."""
        kind = "" if self.met or not self.acceptable_at_roundoff else ", at the rounding level of the member forces"
        return (f"|r| = {self.residual:.3e} against a tolerance of {self.tolerance:.3e} "
                f"(forces in play {self.scale:.3e}, largest residual {self.relative:.1e} of the largest force{kind})")

    def roundoff_failure(self) -> str:
        """Why a residual stalled above the tolerance is not converged."""
        return (f"the residual stalled at {self.residual:.3e}, its largest entry {self.relative:.1e} of the largest "
                f"force in play ({self.scale_max:.3e}); that is the rounding level of the stiffest members' forces "
                f"(about {self.roundoff:.3e}) and above both the tolerance {self.tolerance:.3e} and the "
                f"{self.roundoff_rtol:.0e} accepted at round-off: the model's stiffness contrast is too large "
                "for double precision to balance these forces")


def roundoff_level(K_diagonal: np.ndarray, q: np.ndarray) -> float:
    """Rounding level of a residual's norm: each member force is known to ``eps k |x|``.

    ``K_diagonal`` is the tangent's diagonal (member stiffnesses summed per
    DOF) and ``q`` the state, whose largest coordinate bounds the rounding of
    every member vector.
    """
    return EPS * float(np.linalg.norm(K_diagonal)) * float(np.max(np.abs(q), initial=0.0))


class Tolerances(Protocol):
    """The tolerances of an equilibrium test, as every solver's options carry them."""

    rtol: float
    atol: float
    roundoff_rtol: float


def check(system, q: np.ndarray, lam: float, r: np.ndarray, tolerances: Tolerances,
          K_diagonal: np.ndarray | None = None, play: tuple[float, float] | None = None) -> EquilibriumCheck:
    """The equilibrium test of state ``q`` with residual ``r`` (all DOFs).

    ``tolerances``: ``rtol``, ``atol`` and ``roundoff_rtol`` (a solver's options).
    ``K_diagonal`` (the free tangent's diagonal) gives the rounding level; without
    it the rounding level is taken as zero and only the tolerance counts.
    ``play``: :func:`forces_in_play` of ``q`` when the caller has it already.
    """
    rf = r[system.free]
    play = forces_in_play(system, q, lam) if play is None else play
    ext = system.external_force(lam)
    reactions = r[system.constrained]
    scale = max(play[0], float(np.linalg.norm(ext)), float(np.linalg.norm(reactions)))
    scale_max = max(play[1], _max_abs(ext), _max_abs(reactions))
    floor = roundoff_level(K_diagonal, q) if K_diagonal is not None else 0.0
    return EquilibriumCheck(float(np.linalg.norm(rf)), scale, tolerances.rtol * scale + tolerances.atol, floor,
                            tolerances.roundoff_rtol, float(np.linalg.norm(ext)), _max_abs(rf), scale_max)


def forces_in_play(system, q: np.ndarray, lam: float) -> tuple[float, float]:
    """Norm and largest entry of :meth:`~shellform.assembly.System.forces_in_play` on the free DOFs."""
    play = system.forces_in_play(q, lam)[system.free]
    return float(np.linalg.norm(play)), _max_abs(play)


def _max_abs(v: np.ndarray) -> float:
    return float(np.max(np.abs(v), initial=0.0))
