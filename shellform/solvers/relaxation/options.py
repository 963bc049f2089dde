"""The options of a relaxation: one typed dataclass, defaults written once.

:class:`RelaxationOptions` holds what a user chooses (scheme, tolerances,
limits, linear solver); :class:`Refinements` the implicit scheme's
refinements, each on by default because a benchmark across net sizes shows
its gain (``benchmarks/bench_mra.py``). They are switched off only to measure
that gain again, which is what the benchmarks and tests do.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ...errors import ModelError

SCHEMES = ("rk4", "kinetic", "implicit")
START_STATES = ("auto", "reference", "force_density")


@dataclass(frozen=True)
class Refinements:
    """The implicit scheme's refinements (all on by default).

    Attributes
    ----------
    slack_active_set : bool
        Solve each step again with the slack ropes it would stretch modelled
        as taut (:func:`~.active_set.engage_slack_ropes`, at most two more
        solves per step). A slack rope has no stiffness, so a plain step
        overshoots wherever it pulls one taut and the line search must cut
        it. The three refinements below work on patches of the net and need
        the active set: without it a step of the whole net overshoots where
        it pulls slack ropes taut, and the patches' steps, taken from there,
        only add to it.
    front_sweeps : bool
        After a step that leaves only a few nodes far from balance, take
        Newton steps on the patch of nodes around them with the rest of the
        net held (:func:`~.patch_steps.sweep_fronts`).
    factor_correction : bool
        Before refactorising, try the kept factor corrected by an exact solve
        on the nodes whose tangent entries changed since it was made
        (:class:`~.local_correction.LocalCorrection`).
    slack_settling : bool
        When a step gets ropes' slack state wrong (slack ropes it stretches
        outside its active set, taut ones it shortens below their rest
        length), settle them on the patch of nodes around them
        (:func:`~.active_set.settle_slack_set`).
    step_repair : bool
        When a few ropes make the whole net's step overshoot, keep the full
        step and relax the patch of nodes around them from there instead of
        cutting the step (:func:`~.patch_steps.repair_full_step`).

    The patch refinements apply only to nets of axial members under constant
    loads (:func:`~.patch.patchable`); elsewhere they are skipped.
    """

    slack_active_set: bool = True
    front_sweeps: bool = True
    factor_correction: bool = True
    slack_settling: bool = True
    step_repair: bool = True

    @property
    def on_patches(self) -> bool:
        """Whether any refinement works on patches (each needs the active set)."""
        return self.slack_active_set and (self.front_sweeps or self.slack_settling or self.step_repair)


@dataclass(frozen=True, kw_only=True)
class RelaxationOptions:
    """How :func:`~shellform.solvers.relaxation.relax` lets a net fall to rest.

    Attributes
    ----------
    scheme : {"implicit", "rk4", "kinetic"}
        See :mod:`shellform.solvers.relaxation`.
    lam, mu : float
        Load factor and prescribed-displacement parameter.
    extra_mass : float or array_like, optional
        Extra nodal inertia [kg] added to ``Structure.nodal_mass()``.
    damping : float, optional
        Viscous damping per unit mass ``c_i / m_i`` [1/s] (``rk4``; the
        implicit scheme adds it to the pseudo-time term). Default
        ``2 sqrt(g / L)``: critical damping of a pendulum of the net's size.
    rtol : float
        Default tolerances: acceleration ``rtol * g`` and velocity
        ``rtol * sqrt(g L)``, with ``g`` the largest load-over-mass of a node
        and ``L`` the size of the net.
    velocity_tol, acceleration_tol : float, optional
        Explicit tolerances [m/s], [m/s^2]; every node must meet both.
    dt : float, optional
        Time step of the explicit schemes (default: 90 % of the stability
        bound) or the first pseudo time step of the implicit one.
    max_iterations : int, optional
        Give up after this many steps (default 2,000,000 explicit, 500 implicit).
    max_wall_time : float, optional
        Give up after this many seconds.
    linear_solver : {"auto", "cholesky", "ldl", "nd", "amg", "direct", "lu"}
        Linear solver of the implicit scheme
        (:class:`~shellform.solvers.relaxation.linalg.SPDSolve`).
    progress_every : int, optional
        Call the progress callback every so many iterations (default 1 for
        the implicit scheme, 2000 for the explicit ones).
    refinements : Refinements
        The implicit scheme's refinements, all on by default.
    """

    scheme: str = "implicit"
    lam: float = 1.0
    mu: float = 0.0
    extra_mass: float | np.ndarray | None = None
    damping: float | None = None
    rtol: float = 1e-6
    velocity_tol: float | None = None
    acceleration_tol: float | None = None
    dt: float | None = None
    max_iterations: int | None = None
    max_wall_time: float | None = None
    linear_solver: str = "auto"
    progress_every: int | None = None
    refinements: Refinements = field(default_factory=Refinements)

    def __post_init__(self):
        if self.scheme not in SCHEMES:
            raise ModelError(f"relaxation: unknown scheme {self.scheme!r}; expected one of {SCHEMES}")

    @property
    def iteration_limit(self) -> int:
        """``max_iterations``, or the scheme's default."""
        if self.max_iterations is not None:
            return int(self.max_iterations)
        return 500 if self.scheme == "implicit" else 2_000_000

    @property
    def report_every(self) -> int:
        """``progress_every`` (at least 1), or the scheme's default."""
        if self.progress_every is None:
            return 1 if self.scheme == "implicit" else 2000
        return max(int(self.progress_every), 1)
