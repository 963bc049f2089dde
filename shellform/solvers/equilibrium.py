"""When a residual counts as equilibrium.

Converged means the forces balance: the free residual is small against the
forces in play at the state (:meth:`~shellform.assembly.System.forces_in_play`,
the applied loads and the reactions), ``|r| <= rtol * scale + atol``. The
scale never grows with a member's stiffness, so a stiff member cannot hide an
unbalanced load.

A residual is a sum of member forces, each computed from coordinates known to
machine precision only: a member of axial stiffness ``EA / L`` rounds its force
to about ``eps EA |x| / L``. Where that rounding level lies above the
tolerance no iteration can meet it; the solvers then stop when the residual
stalls there and call the state converged only when its relative residual is
still below ``roundoff_rtol`` (default ``1e-6`` of the forces in play). Above
that the result is an honest failure that names the achieved residual and the
reason: an exact answer for a model with members ``10^12`` times stiffer than
others needs more digits than a double has.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

EPS = float(np.finfo(float).eps)
#: largest residual, relative to the forces in play, accepted where round-off stops the iteration
ROUNDOFF_RTOL = 1e-6


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
    """

    residual: float
    scale: float
    tolerance: float
    roundoff: float = 0.0
    roundoff_rtol: float = ROUNDOFF_RTOL
    applied: float = float("nan")

    @property
    def relative(self) -> float:
        """Residual relative to the forces in play."""
        return self.residual / self.scale if self.scale > 0 else (0.0 if self.residual == 0 else float("inf"))

    @property
    def met(self) -> bool:
        """The residual meets the tolerance."""
        return bool(self.residual <= self.tolerance)

    @property
    def at_roundoff(self) -> bool:
        """The residual is within the rounding level, where iterating further cannot help."""
        return bool(self.residual <= self.roundoff)

    @property
    def acceptable_at_roundoff(self) -> bool:
        """Stalled at the rounding level with a relative residual still small enough to call converged.

        Where nothing is loaded and the forces in play are themselves below
        the rounding of one member force (a rigid motion under prescribed
        displacements: a tenth of :func:`roundoff_level`, which carries a
        safety factor of ten), the state is force-free as far as doubles can
        tell, and any residual at the rounding level is accepted. Applied loads
        are never noise: they must be balanced.
        """
        noise = self.applied == 0.0 and self.scale <= 0.1 * self.roundoff
        return self.at_roundoff and bool(noise or self.residual <= self.roundoff_rtol * self.scale)

    def describe(self) -> str:
        """The residual against its tolerance, in words."""
        return (f"|r| = {self.residual:.3e} against a tolerance of {self.tolerance:.3e} "
                f"(forces in play {self.scale:.3e}, relative residual {self.relative:.1e})")

    def roundoff_failure(self) -> str:
        """Why a residual stalled above the tolerance is not converged."""
        return (f"the residual stalled at {self.residual:.3e}, relative residual {self.relative:.1e} of the forces "
                f"in play ({self.scale:.3e}); that is the rounding level of the stiffest members' forces "
                f"(about {self.roundoff:.3e}) and above both the tolerance {self.tolerance:.3e} and the "
                f"{self.roundoff_rtol:.0e} accepted at round-off: the model's stiffness contrast is too large "
                "for double precision to balance these forces")


def force_scale(system, q: np.ndarray, lam: float, r: np.ndarray) -> tuple[float, float]:
    """Forces in play at ``q`` with residual ``r`` (all DOFs), and the norm of the applied loads.

    See :class:`EquilibriumCheck`.
    """
    play = float(np.linalg.norm(system.forces_in_play(q, lam)[system.free]))
    applied = float(np.linalg.norm(system.external_force(lam)))
    return max(play, applied, float(np.linalg.norm(r[system.constrained]))), applied


def roundoff_level(K_diagonal: np.ndarray, q: np.ndarray) -> float:
    """Rounding level of a residual: each member force is known to ``eps k |x|``.

    Ten times that estimate, so that a residual stalled at the true rounding
    level is recognised as such.

    ``K_diagonal`` is the tangent's diagonal (member stiffnesses summed per
    DOF) and ``q`` the state, whose largest coordinate bounds the rounding of
    every member vector.
    """
    return 10.0 * EPS * float(np.linalg.norm(K_diagonal)) * float(np.max(np.abs(q), initial=0.0))


def check(system, q: np.ndarray, lam: float, r: np.ndarray, rtol: float, atol: float,
          K_diagonal: np.ndarray | None = None, roundoff_rtol: float = ROUNDOFF_RTOL) -> EquilibriumCheck:
    """The equilibrium test of state ``q`` with residual ``r`` (all DOFs)."""
    norm = float(np.linalg.norm(r[system.free]))
    scale, applied = force_scale(system, q, lam, r)
    floor = roundoff_level(K_diagonal, q) if K_diagonal is not None else 0.0
    return EquilibriumCheck(norm, scale, rtol * scale + atol, floor, roundoff_rtol, applied)
