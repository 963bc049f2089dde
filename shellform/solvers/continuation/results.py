"""What a continuation run returns: path points, critical points and the result object."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

TABLE_COLUMNS = (
    "step", "branch", "arc_length", "lam", "mu", "parameter", "load", "displacement",
    "n_negative", "iterations", "ds",
)


@dataclass
class PathLocation:
    """Where a state lies on the path.

    Attributes
    ----------
    arc_length : float
    lam, mu : float
        Load factor and magnitude of the prescribed displacements.
    parameter : float
        The continuation parameter (``lam`` or ``mu``).
    load : float
        Generalised load: ``lam`` under load control, the reaction conjugate
        to ``mu`` under displacement control.
    displacement : float
        Displacement measure conjugate to ``load``.
    """

    arc_length: float
    lam: float
    mu: float
    parameter: float
    load: float
    displacement: float


@dataclass
class PathPoint(PathLocation):
    """One converged point of the path (what a progress callback receives).

    ``residual`` is the norm of the free residual at the point and
    ``tolerance`` what equilibrium asks of it there (``rtol`` times the forces
    in play at the point, plus ``atol``). ``n_negative`` is -1 where it was
    not counted: everywhere with ``stability`` off, except at points whose
    tangent a Cholesky factorisation proved positive definite (0; without
    ``stability`` that tangent may be the corrector's last one, a last
    correction away from the point, see ``REUSE_DISTANCE`` in
    :mod:`~shellform.solvers.continuation.corrector`).
    """

    step: int
    branch: int
    n_negative: int
    iterations: int
    ds: float
    q: np.ndarray
    monitors: dict[str, float] = field(default_factory=dict)
    residual: float = float("nan")
    tolerance: float = float("nan")


@dataclass
class PathEvent(PathLocation):
    """A critical point found along the path.

    Attributes
    ----------
    kind : {"limit", "bifurcation"}
        ``"limit"``: the parameter turns (``dp/ds`` changes sign).
        ``"bifurcation"``: the count of negative eigenvalues changes while the
        parameter keeps its direction.
    step : int
        Step at whose end the event was detected (it lies between points
        ``step - 1`` and ``step``).
    arc_length, lam, mu, parameter, load, displacement : float
        Location (:class:`PathLocation`).
    n_negative_before, n_negative_after : int
        Negative-eigenvalue counts at the ends of the step.
    located : bool
        Whether bisection reached the tolerance.
    bracket : float
        Parameter width of the final bisection bracket (for a limit point the
        parameter error is far smaller than this).
    arc_bracket : float
        Arc-length width of the final bracket.
    eigenvalue : float
        Eigenvalue of the free tangent closest to zero at the located point.
    mode : ndarray, shape (n_dof,)
        Its eigenvector on all DOFs (zero at constrained DOFs), unit norm.
    q : ndarray, shape (n_dof,)
        State at the located point.
    reactions : ndarray, shape (n_dof,)
        Support reactions at the located point.
    tangent : ndarray, shape (n_free + 1,)
        Path tangent ``(du/ds, dp/ds)`` at the located point (direction of
        travel), used for branch switching.
    switched : bool
        The tracer left the primary branch here.
    message : str
    history : tuple or None
        The rod frames ``q`` was found with (``system.history()``; None
        without rods): its twists, torques and reactions are evaluated with
        them (``shellform.io.state_mesh(..., history=)``).
    """

    kind: str
    step: int
    n_negative_before: int
    n_negative_after: int
    located: bool
    bracket: float
    arc_bracket: float
    eigenvalue: float
    mode: np.ndarray
    q: np.ndarray
    reactions: np.ndarray
    tangent: np.ndarray
    switched: bool = False
    message: str = ""
    history: tuple | None = None

    _SCALARS = (
        "kind", "step", "arc_length", "lam", "mu", "parameter", "load", "displacement",
        "n_negative_before", "n_negative_after", "located", "bracket", "arc_bracket",
        "eigenvalue", "switched", "message",
    )

    def to_dict(self) -> dict:
        """JSON-ready summary (no arrays)."""
        out = {}
        for k in self._SCALARS:
            v = getattr(self, k)
            out[k] = v.item() if isinstance(v, np.generic) else v
        return out


@dataclass
class ContinuationResult:
    """Outcome of a continuation run.

    Attributes
    ----------
    success : bool
        False when the run ended because a step failed (not for a bound).
    message : str
    status : str
        Why the run ended: ``"max_steps"``, ``"parameter_bound"``,
        ``"displacement_bound"``, ``"event"``, ``"callback"``, ``"failed"``.
    control : str
    steps : int
        Accepted steps in the whole path (including resumed ones).
    rejected_steps : int
        Steps cut back and retried.
    newton_iterations : int
        Corrector iterations of accepted and rejected steps.
    table : dict of str to ndarray
        One entry per path point: the columns of ``TABLE_COLUMNS`` plus the
        requested monitors.
    states : list of ndarray
        Full DOF vectors of the path points (``state_steps`` gives their
        step numbers; a resumed run has those of its checkpoint too); empty
        when states were not stored.
    state_histories : list
        The rod frames each of ``states`` was found with (``system.history()``
        then; None entries without rods).
    events : list of PathEvent
    timings : dict of str to float
        Wall time [s]: ``assembly`` (residual and tangent), ``linear_algebra``
        (factorisations and solves), ``stability`` (inertia checks beyond the
        factorisation, critical modes), ``event_location`` (bisection, which
        includes its own assembly and linear algebra), ``total``.
    monitors : tuple of str
        Names of the extra table columns.
    parameter_scale : float
        ``c`` of the arc-length metric ``|du|^2 + c^2 dp^2`` (0 for cylindrical).
    """

    success: bool
    message: str
    status: str
    control: str
    steps: int
    rejected_steps: int
    newton_iterations: int
    table: dict[str, np.ndarray]
    states: list[np.ndarray]
    state_steps: list[int]
    events: list[PathEvent]
    timings: dict[str, float]
    monitors: tuple[str, ...] = ()
    parameter_scale: float = 0.0
    state_histories: list = field(default_factory=list)

    def __getitem__(self, column: str) -> np.ndarray:
        return self.table[column]

    @property
    def n_points(self) -> int:
        return len(self.table["step"])

    def events_of(self, kind: str) -> list[PathEvent]:
        return [e for e in self.events if e.kind == kind]

    def summary(self) -> dict:
        """JSON-ready summary: outcome, counts, bounds of the path, events."""
        t = self.table
        return {
            "success": bool(self.success),
            "message": self.message,
            "status": self.status,
            "control": self.control,
            "steps": int(self.steps),
            "rejected_steps": int(self.rejected_steps),
            "newton_iterations": int(self.newton_iterations),
            "points": int(self.n_points),
            "parameter_range": [float(np.min(t["parameter"])), float(np.max(t["parameter"]))],
            "load_range": [float(np.min(t["load"])), float(np.max(t["load"]))],
            # -1 unless every point was counted: a maximum over some points would claim too much
            "max_negative_eigenvalues": int(np.max(t["n_negative"])) if np.min(t["n_negative"]) >= 0 else -1,
            "events": [e.to_dict() for e in self.events],
            "timings_s": {k: float(v) for k, v in self.timings.items()},
        }
