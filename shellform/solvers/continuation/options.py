"""The settings of a continuation run: one typed object, defaults written once."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..equilibrium import ROUNDOFF_RTOL
from ..options import with_overrides

CONTROLS = ("load", "displacement")
CONSTRAINTS = ("spherical", "cylindrical")
ON_BIFURCATION = ("continue", "switch", "stop")
LINEAR_SOLVERS = ("ldl", "lu")


@dataclass(frozen=True)
class ContinuationOptions:
    """Options of :func:`~shellform.solvers.continuation.trace_path`.

    Attributes
    ----------
    ds : float
        First arc length (displacement units). Default: from ``initial_increment``.
    initial_increment : float
        First parameter increment (sets ``ds``). Default: the smaller of 1/20 of
        the distance to the parameter bound in the direction of travel and a
        quarter of the linearised distance to the nearest critical point
        (:mod:`shellform.solvers.step_bounds`).
    ds_min, ds_max : float
        Step-length bounds (default ``1e-6 ds`` and ``10 ds``, the latter capped
        by the linearised distance to the nearest critical point).
    constraint : {"spherical", "cylindrical"}
        Arc-length constraint; cylindrical measures only the free DOFs.
    psi : float
        Weight of the parameter in the spherical constraint (``c = psi |dG/dp| / k``
        with ``k`` the larger of the mean tangent diagonals at the start and at the
        reference state).
    parameter_scale : float
        Override for ``c`` in ``|du|^2 + c^2 dp^2 = ds^2``.
    max_steps : int
        Accepted steps.
    parameter_bounds : (float, float)
        Stop when the parameter leaves this interval.
    land_on_bounds : bool
        Make the last point lie exactly on the bound it crossed.
    max_displacement : float
        Stop when a free DOF moves further than this from the reference.
    rtol, atol : float
        Corrector tolerance ``|G| <= rtol * scale + atol``; ``scale`` is the
        forces in play (the member forces at the last accepted point, the
        applied loads and the reactions; the predictor's residual while all
        are zero). See :mod:`shellform.solvers.equilibrium`.
    roundoff_rtol : float
        A corrector residual within the rounding level of the member forces
        (``eps |diag K| max|q|`` at the start) is accepted while its largest
        entry is below this fraction of the largest force in play; one that
        stalls there above it fails the step, which says why.
    max_iterations : int
        Corrector iterations before a cut-back.
    target_iterations : int
        Step length grows when fewer, shrinks when more iterations were needed.
    max_angle_deg : float
        Reject (and cut back) a step whose converged point lies further than
        this angle from the predictor: a guard against branch jumping.
    max_inertia_cutbacks : int
        Cut-backs allowed when the negative-eigenvalue count jumps by more than
        one in a step (two critical points in one step, or a jump).
    stability : bool
        Count negative eigenvalues at every point (needed for bifurcations).
    definite_branch : bool
        Without ``stability``: the caller traces a branch it knows stable (it
        counts for itself and stops at the first unstable point), so every
        tangent is factorised by Cholesky first, LDL^T where that fails.
    detect_events : bool
        Detect and locate limit and bifurcation points.
    critical_rtol : float
        Critical points are located until their critical load (the path
        parameter) is known to this relative tolerance
        (:mod:`~shellform.solvers.continuation.events`).
    locate_tol : float
        Location also stops when the bracket is this fraction of the step length.
    on_bifurcation : {"continue", "switch", "stop"}
        Stay on the primary branch, follow the secondary branch, or stop.
    branch_side : {1, -1}
        Which half of the secondary branch to follow (sign of the mode).
    switch_direction : ndarray (n_dof,), optional
        Imperfection shape to leave the bifurcation along instead of the
        critical mode.
    switch_ds : float
        Arc length of the switching step (default: the current step length).
    max_switches : int
        Bifurcations at which to switch.
    stop_after_events : int
        Stop when this many events have been found.
    fixed_lam, fixed_mu : float
        The parameter that is not the path parameter (default: loads in full,
        prescribed DOFs at the reference).
    monitors : dict
        Extra table columns: ``name -> DOF index`` (displacement of that DOF) or
        ``name -> callable(q, lam, mu) -> float``.
    eigenvalue_column : bool
        Record at every point the eigenvalue of the free tangent nearest zero
        (table column ``eigenvalue``): a critical point is where it crosses
        zero, and how near the path comes to one shows between events. It
        costs a Lanczos run on the point's own factor per point (NaN where
        that does not converge in ``EIGENVALUE_ITERATIONS``).
    displacement_dof : int
        DOF whose displacement (in the direction of its load) is the
        ``displacement`` column under load control; default the most loaded DOF.
    store_states : bool
        Keep every state in ``result.states``.
    linear_solver : {"ldl", "lu"}
        ``"ldl"``: qdldl factorisation for the Newton solves and the inertia
        (LU fallback). ``"lu"``: SuperLU solves and a separate LDL for the inertia.
    """

    ds: float | None = None
    initial_increment: float | None = None
    ds_min: float | None = None
    ds_max: float | None = None
    constraint: str = "spherical"
    psi: float = 1.0
    parameter_scale: float | None = None
    max_steps: int = 200
    parameter_bounds: tuple[float, float] = (-np.inf, np.inf)
    max_displacement: float | None = None
    rtol: float = 1e-10
    atol: float = 0.0
    roundoff_rtol: float = ROUNDOFF_RTOL
    max_iterations: int = 15
    target_iterations: int = 4
    max_angle_deg: float = 45.0
    max_inertia_cutbacks: int = 1
    stability: bool = True
    definite_branch: bool = False
    detect_events: bool = True
    critical_rtol: float = 1e-6
    locate_tol: float = 1e-8
    on_bifurcation: str = "continue"
    branch_side: int = 1
    switch_direction: Any = None
    switch_ds: float | None = None
    max_switches: int = 1
    stop_after_events: int | None = None
    fixed_lam: float = 1.0
    fixed_mu: float = 0.0
    monitors: dict = field(default=None)
    eigenvalue_column: bool = False
    displacement_dof: int | None = None
    store_states: bool = True
    linear_solver: str = "ldl"
    land_on_bounds: bool = True

    def __post_init__(self):
        if self.constraint not in CONSTRAINTS:
            raise ValueError(f"constraint must be one of {CONSTRAINTS}, got {self.constraint!r}")
        if self.linear_solver not in LINEAR_SOLVERS:
            raise ValueError(f"linear_solver must be 'ldl' or 'lu', got {self.linear_solver!r}")
        if self.on_bifurcation not in ON_BIFURCATION:
            raise ValueError(f"on_bifurcation must be 'continue', 'switch' or 'stop', got {self.on_bifurcation!r}")
        lo, hi = self.parameter_bounds
        object.__setattr__(self, "parameter_bounds", (float(lo) if lo is not None else -np.inf,
                                                      float(hi) if hi is not None else np.inf))

    def settings(self) -> dict:
        """The options a path depends on (a resumed run must match them): all but the step budget
        and what is kept in memory."""
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(self)
                if f.name not in ("max_steps", "store_states", "monitors")}


def make_options(options: ContinuationOptions | None = None, **overrides) -> ContinuationOptions:
    """``options`` (default: the defaults) with ``overrides`` by name; an unknown name is a TypeError."""
    return with_overrides(ContinuationOptions, options, overrides, "continuation")
