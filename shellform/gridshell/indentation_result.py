"""What an indentation run found: its snaps and the traced path."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class Snap:
    """A snapping point of the indentation path.

    Attributes
    ----------
    dD : float
        Apex displacement at the critical point [m].
    dD_over_R : float
    force_before, force_after : float
        Normalised force ``-sum(F_z) R^2 / EI`` at the critical point and in
        the stable state reached after the snap.
    kind : str
        ``"limit"`` (the path folds back in ``dD``) or ``"bifurcation"``
        (stability lost while ``dD`` keeps increasing), as the tracer
        classified it; ``"unlocated"`` when bisection did not converge and
        the last stable point is reported.
    located : bool
    label_before, label_after : str
        Configuration before and after (:func:`~shellform.gridshell.configurations.classify_configuration`).
    jump : float
        Largest node displacement during the snap, relative to ``R``.
    merged : int
        Further losses of stability right after landing, merged into this snap.
    """

    dD: float
    dD_over_R: float
    force_before: float
    force_after: float
    kind: str
    located: bool
    label_before: str = ""
    label_after: str = ""
    jump: float = 0.0
    merged: int = 0

    def to_dict(self) -> dict:
        return {k: (float(v) if isinstance(v, (float, np.floating)) else v) for k, v in self.__dict__.items()}


@dataclass
class IndentationResult:
    """A traced indentation path.

    Attributes
    ----------
    dD, force : ndarray
        Apex displacement [m] and indentation force ``-sum(F_z)`` [N] at every
        stable path point, in path order (``dD`` increases, with a repeated
        value where the structure snaps).
    segment : ndarray of int
        Stable segment of every point (a snap starts a new segment).
    n_negative : ndarray of int
        Negative eigenvalues of the tangent at every point (0 on stable points).
    snaps : list of Snap
    exchanges : list of Snap
        Losses of stability where the path continued smoothly on a stable
        branch crossing there (no jump).
    labels : list of str
        Configuration of every point.
    states : dict of float to ndarray
        Selected states keyed by ``dD / R``: segment ends, critical points
        and the states reached after them.
    path_states : list of ndarray
        State of every path point (only with ``store_states``).
    state_histories, path_histories : dict, list
        The rod frames each of ``states`` and ``path_states`` was found with
        (``system.history()`` then): a state's twists, torques and reactions
        are evaluated with its own (``shellform.io.state_mesh(..., history=)``).
    success : bool
    message : str
    steps, newton_iterations, rejected_steps : int
    n_dof, n_free : int
    wall_time_s : float
    timings : dict
    """

    mode: str
    radius: float
    force_scale: float
    dD: np.ndarray
    force: np.ndarray
    segment: np.ndarray
    n_negative: np.ndarray
    snaps: list
    labels: list
    states: dict
    success: bool
    message: str
    steps: int
    newton_iterations: int
    rejected_steps: int
    n_dof: int
    n_free: int
    wall_time_s: float
    timings: dict = field(default_factory=dict)
    exchanges: list = field(default_factory=list)
    path_states: list = field(default_factory=list)
    state_histories: dict = field(default_factory=dict)
    path_histories: list = field(default_factory=list)

    @property
    def x(self) -> np.ndarray:
        """``dD / R``."""
        return self.dD / self.radius

    @property
    def y(self) -> np.ndarray:
        """``-sum(F_z) R^2 / EI``."""
        return self.force / self.force_scale

    @property
    def thresholds(self) -> list[float]:
        """Snapping thresholds ``dD / R`` in path order."""
        return [s.dD_over_R for s in self.snaps]

    @property
    def max_force(self) -> float | None:
        """Largest normalised force along the path (None for a path without a point: nothing was computed)."""
        return float(np.max(self.y)) if self.y.size else None

    def summary(self) -> dict:
        return {
            "mode": self.mode,
            "success": bool(self.success),
            "message": self.message,
            "thresholds_dD_over_R": [float(t) for t in self.thresholds],
            "snaps": [s.to_dict() for s in self.snaps],
            "stability_exchanges": [s.to_dict() for s in self.exchanges],
            "max_force_normalised": self.max_force,
            "steps": int(self.steps),
            "newton_iterations": int(self.newton_iterations),
            "rejected_steps": int(self.rejected_steps),
            "n_dof": int(self.n_dof),
            "n_free": int(self.n_free),
            "wall_time_s": float(self.wall_time_s),
            "labels": sorted(set(self.labels), key=self.labels.index),
        }
