"""What a relaxation reports: progress to a callback, and its result."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class RelaxationProgress:
    """What a progress callback receives.

    ``q`` and ``v`` are the current state (all DOFs, copies the callback may
    keep): saving ``q`` is a checkpoint. The equilibrium is the minimum of a
    convex potential, so ``relax(system, q0=saved_q)`` (for the explicit
    schemes also ``v0=saved_v`` to continue the same trajectory) reaches the
    same shape as an uninterrupted run. For the implicit scheme ``v`` is the
    last pseudo step over its pseudo time step, and a restart ignores it.
    """

    scheme: str
    iteration: int
    time: float
    max_velocity: float
    max_acceleration: float
    residual_norm: float
    wall_time_s: float
    q: np.ndarray | None = None
    v: np.ndarray | None = None


@dataclass
class RelaxationResult:
    """Outcome of a relaxation.

    Attributes
    ----------
    q : ndarray
        Final DOF vector (the last finite state when the run failed).
    v : ndarray
        Final velocity of every DOF (zero at constrained DOFs).
    success : bool
        Every nodal velocity and acceleration met its tolerance.
    message : str
        What happened, in words.
    scheme : str
        ``"rk4"``, ``"kinetic"`` or ``"implicit"``.
    iterations : int
        Time steps (explicit schemes) or accepted pseudo-time steps (implicit).
    max_velocity, max_acceleration : float
        Largest nodal speed [m/s] and nodal acceleration magnitude [m/s^2] at
        the final state; the acceleration is the out-of-balance force over the
        physical mass, ``|r_i| / m_i``, except for ``"rk4"``, which reports the
        acceleration of its equation of motion, ``|r_i + c_i v_i| / m_i``
        (the same at rest).
    residual_norm : float
        Euclidean norm of the out-of-balance force at the free DOFs [N].
    velocity_tol, acceleration_tol : float
        The tolerances used.
    time : float
        Simulated time (explicit schemes) or accumulated pseudo time.
    time_step : float
        Time step of the explicit schemes; last pseudo time step (implicit).
    wall_time_s : float
    reactions : ndarray
        Support reactions at every DOF (zero where free) at the final state.
    residual_evaluations, factorizations, rejected_steps, linear_iterations : int
        Work counters (``linear_iterations``: preconditioned CG iterations of
        the implicit scheme).
    local_steps : int
        Newton steps of the implicit scheme on patches around the nodes that
        were furthest from balance, the rest of the net held
        (:func:`~.patch_steps.sweep_fronts`); not counted in ``iterations`` or
        ``factorizations``.
    corrected_solves : int
        Solves of the implicit scheme by CG with the kept factor corrected on
        the nodes whose tangent entries had changed (:class:`~.linalg.SPDSolve`).
    repaired_steps : int
        Steps of the implicit scheme kept at full length with the patch
        around the few ropes that made them overshoot relaxed from there
        (:func:`~.patch_steps.repair_full_step`); counted in ``iterations``.
    history : dict of lists
        ``iteration``, ``max_velocity``, ``max_acceleration``,
        ``residual_norm`` sampled every ``progress_every`` iterations.
    start : str
        ``"given"`` (``q0`` was passed), ``"reference"`` or ``"force_density"``;
        :func:`~shellform.mra.form_find` reports ``"coarse_net"`` for its start
        from a coarser net (whose relaxation time is then in ``wall_time_s``).
    """

    q: np.ndarray
    v: np.ndarray
    success: bool
    message: str
    scheme: str
    iterations: int
    max_velocity: float
    max_acceleration: float
    residual_norm: float
    velocity_tol: float
    acceleration_tol: float
    time: float
    time_step: float
    wall_time_s: float
    reactions: np.ndarray
    residual_evaluations: int = 0
    factorizations: int = 0
    rejected_steps: int = 0
    linear_iterations: int = 0
    local_steps: int = 0
    corrected_solves: int = 0
    repaired_steps: int = 0
    history: dict = field(default_factory=dict)
    start: str = "reference"
