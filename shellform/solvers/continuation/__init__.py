"""Arc-length continuation of equilibrium paths with stability and event detection.

The path is the solution set of ``G(u, p) = 0``, with ``u`` the free DOFs and
``p`` one scalar parameter: the load factor (``control="load"``) or the
magnitude of the prescribed displacements (``control="displacement"``;
:mod:`~shellform.solvers.continuation.problem`). Each step predicts along the
path tangent and corrects with Newton's method on ``G`` plus the arc-length
constraint

    |du|^2 + c^2 dp^2 = ds^2          (spherical; ``c = 0``: cylindrical),

where ``c = psi * |dG/dp| / k`` (``k`` the larger of the mean diagonals of the
tangent at the starting and at the reference state) is the displacement per
unit parameter of a typical stiffness, so both parts of the metric have the
same weight for ``psi = 1`` (:mod:`~shellform.solvers.continuation.corrector`).

After each accepted step the inertia of the free tangent (number of negative
eigenvalues, :mod:`shellform.solvers.stability`) is compared with the last
point. A sign change of ``dp/ds`` is a *limit point*; a change of the count
while ``p`` keeps its direction is a *bifurcation point*. Both are located by
bisection on the arc length within the step and reported with the state, the
generalised load and the critical mode
(:mod:`~shellform.solvers.continuation.events`). At a bifurcation the tracer
can switch to the secondary branch by predicting along the critical mode
(:mod:`~shellform.solvers.continuation.branches`).

Modules: ``options`` (the typed settings), ``problem`` (``G`` and its linear
algebra), ``start`` (the first point, the metric and the first step), ``corrector``,
``events``, ``branches``, ``tracer`` (the loop), ``snapshot`` (checkpoints),
``results``.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import numpy as np

from ...errors import ModelError
from .options import CONSTRAINTS, CONTROLS, ContinuationOptions, make_options
from .results import TABLE_COLUMNS, ContinuationResult, PathEvent, PathLocation, PathPoint
from .snapshot import Checkpoint, load
from .start import start
from .tracer import Tracer

__all__ = [
    "CONSTRAINTS", "CONTROLS", "TABLE_COLUMNS", "Checkpoint", "ContinuationOptions", "ContinuationResult", "PathEvent",
    "PathLocation", "PathPoint", "switch_branch", "trace_path",
]


def trace_path(
    system,
    control: str = "load",
    q0: np.ndarray | None = None,
    p0: float = 0.0,
    direction: int = 1,
    callback: Callable[[PathPoint], bool | None] | None = None,
    checkpoint: Checkpoint | None = None,
    options: ContinuationOptions | None = None,
    **overrides,
) -> ContinuationResult:
    """Follow the equilibrium path of ``system`` by arc-length continuation.

    Parameters
    ----------
    system : System
        Any assembled system (bars, ropes, rods, joints).
    control : {"load", "displacement"}
        Path parameter: the load factor ``lam`` scaling ``system.load_vector()``
        (prescribed DOFs held at ``fixed_mu``), or the prescribed-displacement
        magnitude ``mu`` (scaled loads held at ``fixed_lam``).
    q0 : ndarray, optional
        Starting guess (all DOFs); equilibrium at ``p0`` is found first.
    p0 : float
        Starting parameter.
    direction : {1, -1}
        Initial direction of travel of the parameter.
    callback : callable, optional
        Called with a :class:`PathPoint` after every converged point (progress
        report, streaming output). Returning True or raising StopIteration
        ends the run cleanly.
    checkpoint : Checkpoint, optional
        Where and how often to save enough to continue the path, and whether
        to resume from a saved state when there is one (a
        :class:`shellform.io.checkpoint.CheckpointFile`). A resumed run keeps
        the table, events and states of the earlier run.
    options : ContinuationOptions, optional
        Typed options (defaults: :class:`ContinuationOptions`).
    **overrides
        Any field of :class:`ContinuationOptions` by name (``ds``, ``parameter_bounds``,
        ``rtol``, ...), applied on top of ``options``.

    Returns
    -------
    ContinuationResult
    """
    tracer = Tracer(system, control, make_options(options, **overrides))
    if checkpoint is not None and not callable(getattr(checkpoint, "write", None)):
        raise TypeError(f"checkpoint: expected a Checkpoint such as shellform.io.checkpoint.CheckpointFile(path, "
                        f"every, resume), got {type(checkpoint).__name__}")
    first = None
    if checkpoint is not None and checkpoint.resume and checkpoint.exists():
        load(tracer, checkpoint)
    else:
        q0 = system.q_ref if q0 is None else np.asarray(q0, dtype=float)
        first = start(tracer, q0, p0, direction)
    return tracer.run(callback, first, checkpoint)


def switch_branch(
    system,
    event: PathEvent,
    control: str = "load",
    side: int = 1,
    direction: np.ndarray | None = None,
    callback: Callable[[PathPoint], bool | None] | None = None,
    options: ContinuationOptions | None = None,
    **overrides,
) -> ContinuationResult:
    """Follow the secondary branch through a located bifurcation point.

    The first step leaves ``event`` along its critical mode (or along
    ``direction``, an imperfection shape on all DOFs) made orthogonal to the
    primary path tangent; the arc-length corrector then converges onto the
    secondary branch. A step that falls back onto the primary branch is
    retried shorter and finally reported as a failure.

    Parameters
    ----------
    system : System
        The system of the run that produced ``event``.
    event : PathEvent
        A located bifurcation (``kind == "bifurcation"``).
    control : {"load", "displacement"}
        Control of the run that produced the event.
    side : {1, -1}
        Which half of the secondary branch.
    direction : ndarray (n_dof,), optional
        Perturbation shape instead of the critical mode.
    options, **overrides
        As for :func:`trace_path`; ``ds`` (or ``initial_increment``) sets the
        step length and ``switch_ds`` the first step.

    Returns
    -------
    ContinuationResult
        Starting at the bifurcation point (step 0, branch 0) with the secondary
        branch as branch 1.
    """
    o = dataclasses.replace(make_options(options, **overrides), branch_side=side)
    tracer = Tracer(system, control, o)
    p_b = event.parameter
    first = start(tracer, event.q, p_b, 1)
    # at the bifurcation the tangent is near-singular: reuse the event's tangent
    t = np.asarray(event.tangent, dtype=float)
    tracer.t_du, tracer.t_dp = t[:-1] / tracer.norm(t[:-1], t[-1]), t[-1] / tracer.norm(t[:-1], t[-1])
    mode = np.asarray(direction if direction is not None else event.mode, dtype=float)
    if mode.shape != (system.n_dof,):
        raise ModelError(f"branch switching direction must have {system.n_dof} entries, got shape {mode.shape}")
    return tracer.run(
        callback, first, switch_from=(tracer.u, tracer.p, tracer.t_du, tracer.t_dp, mode[system.free], 0.0),
    )
