"""The line search of a relaxation step, on the convex potential of the net.

The potential is dominated by the work of the weight, so a converging
relaxation measures its changes effect by effect and member by member
(:func:`energy_change`) rather than as the difference of two totals.
"""

from __future__ import annotations

import numpy as np

from ...effects.loads import ConstantForce
from .ropes import is_axial


def energy_change(system, q0: np.ndarray, q1: np.ndarray, lam: float = 1.0) -> float:
    """``Pi(q1) - Pi(q0)`` summed effect by effect, without the cancellation of two totals.

    The total potential is dominated by the work of the weight, so the
    difference of two totals loses the small changes a converging relaxation
    makes. Axial members give their change member by member
    (:meth:`~shellform.effects.axial.AxialBar.energy_change`); constant
    forces contribute ``-f . (q1 - q0)``; other effects the difference of
    their energies.
    """
    total = 0.0
    for e in system.effects:
        factor = lam if e.scales_with_load else 1.0
        if isinstance(e, ConstantForce):
            total -= factor * float(e.force @ (q1 - q0))
        elif is_axial(e):
            total += factor * e.energy_change(q0, q1)
        else:
            total += factor * (e.energy(q1) - e.energy(q0))
    return total


#: sufficient decrease of the line search: the potential falls by at least this share of the slope
ARMIJO = 1e-4


def sufficient_decrease(dE1, d1, slope) -> bool:
    """Whether the line search takes the full step as it is.

    ``dE1`` and ``d1`` are the change of potential at the full step and its slope there.
    """
    return dE1 <= ARMIJO * slope or (d1 <= 0.0 and dE1 < 0.0)


def line_search(at, slope, rnorm0, tiny, max_eval=12, first=None):
    """Step length along a direction ``p`` for the convex potential ``phi(a) = Pi(q + a p)``.

    ``at(a)`` returns ``(phi(a) - phi(0), r(q + a p), r(q + a p) . p)``. The
    full step is taken when it lowers the potential enough (Armijo) or, at
    round-off level (``tiny``), lowers the residual. Otherwise the minimiser of
    ``phi`` on ``(0, 1)`` is located by regula falsi on ``phi'(a) = r(q + a p) . p``
    (increasing, since ``phi`` is convex). Returns ``(alpha, phi(alpha) - phi(0), r)``;
    alpha 0 means no decrease was found. ``first`` is ``at(1.0)`` when the
    caller has evaluated it already.
    """
    dE1, r1, d1 = at(1.0) if first is None else first
    if np.isfinite(dE1) and np.all(np.isfinite(r1)):
        if sufficient_decrease(dE1, d1, slope):
            return 1.0, dE1, r1
        if tiny and float(np.linalg.norm(r1)) < rnorm0:
            return 1.0, dE1, r1
    # bracket [lo, hi] with phi'(lo) < 0 < phi'(hi)
    lo, dlo = 0.0, slope
    hi, dhi = 1.0, d1 if np.isfinite(d1) else np.inf
    best = (0.0, 0.0, None)
    for _ in range(max_eval):
        # at round-off level phi' need not grow along the step: bisect where the secant has no root
        if np.isfinite(dhi) and dhi > dlo:
            a = hi - dhi * (hi - lo) / (dhi - dlo)
            a = min(max(a, lo + 0.05 * (hi - lo)), hi - 0.05 * (hi - lo))
        else:
            a = 0.5 * (lo + hi)
        dEa, ra, da = at(a)
        if not (np.isfinite(dEa) and np.isfinite(da)):
            hi, dhi = a, np.inf
            continue
        if dEa < best[1]:
            best = (a, dEa, ra)
        if abs(da) <= 0.1 * abs(slope) and dEa < 0.0:
            return a, dEa, ra
        if da < 0:
            lo, dlo = a, da
        else:
            hi, dhi = a, da
    if best[0] > 0 and best[1] <= ARMIJO * best[0] * slope:
        return best
    return 0.0, 0.0, None

