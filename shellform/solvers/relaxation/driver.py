"""The driver of a relaxation: the start state, then the chosen scheme."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import replace

import numpy as np

from ...errors import ModelError
from .bounds import setup
from .explicit import run_kinetic, run_rk4
from .force_density import force_density_start
from .implicit import run_implicit
from .options import START_STATES, RelaxationOptions
from .result import RelaxationProgress, RelaxationResult


def relax(
    system,
    q0: np.ndarray | None = None,
    *,
    options: RelaxationOptions | None = None,
    start: str = "auto",
    v0: np.ndarray | None = None,
    spent_s: float = 0.0,
    callback: Callable[[RelaxationProgress], bool | None] | None = None,
    **fields,
) -> RelaxationResult:
    """Let a net of masses and ropes fall to rest in its hanging shape.

    Parameters
    ----------
    system : System
        Ropes (and bars) with their loads; self-weight enters through the
        System's gravity effect. Constrained DOFs are suspension points.
    q0 : ndarray, optional
        Start state (all DOFs); by default chosen by ``start``. Constrained
        DOFs are set to their prescribed values. A ``q`` saved from a
        :class:`RelaxationProgress` resumes a run.
    options : RelaxationOptions, optional
        Scheme, tolerances, limits, linear solver (defaults: the implicit
        scheme to ``rtol = 1e-6``).
    start : {"auto", "reference", "force_density"}
        Where to start when ``q0`` is not given: the reference state (the
        flat planform, as in the MRA paper) or the force-density shape of
        :func:`~.force_density.force_density_start` (one scalar linear solve;
        the net then skips its free fall). ``"auto"``: the force-density
        shape for the implicit scheme, the reference state for the explicit ones.
    v0 : ndarray, optional
        Start velocity of every DOF (explicit schemes; default rest). With the
        ``q`` and ``v`` of a :class:`RelaxationProgress` an explicit run
        continues on the same trajectory. The implicit scheme starts from rest.
    spent_s : float
        Seconds already spent on the same job before this call (a caller's
        preparation, such as hanging a coarse net first): counted in the
        result's and the progress reports' ``wall_time_s`` and against
        ``options.max_wall_time``.
    callback : callable, optional
        Called with a :class:`RelaxationProgress` every
        ``options.progress_every`` iterations; returning True stops the run
        (reported as not converged).
    **fields
        Fields of :class:`RelaxationOptions` given one by one
        (``relax(system, scheme="rk4")``): they override those of ``options``.

    Returns
    -------
    RelaxationResult
    """
    options = RelaxationOptions() if options is None else options
    if fields:
        options = replace(options, **fields)
    if start not in START_STATES:
        raise ModelError(f"relaxation: unknown start {start!r}; expected one of {START_STATES}")
    if not (np.isfinite(spent_s) and spent_s >= 0):
        raise ModelError(f"relaxation: spent_s must be a finite, non-negative time, got {spent_s!r}")
    t0 = time.perf_counter() - spent_s
    st = setup(system, q0, options, v0)
    if q0 is not None:
        st.start = "given"
    implicit = options.scheme == "implicit"
    fd_start = q0 is None and (start == "force_density" or (start == "auto" and implicit))
    if implicit:
        # started from the force-density shape of the first stiffness stage
        return run_implicit(system, st, options, callback, t0, fd_start=fd_start)
    if fd_start:
        q_fd = force_density_start(system, options.lam, base=st.q)
        if q_fd is not None:
            st.q, st.start = q_fd, "force_density"
    return {"rk4": run_rk4, "kinetic": run_kinetic}[options.scheme](system, st, options, callback, t0)
