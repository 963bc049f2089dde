"""Static equilibrium of rod networks in load steps.

Rod effects carry reference frames from one accepted state to the next
(:mod:`shellform.effects.rod_kinematics`). Static Newton (:func:`solve_static`) works
on a rod network as it is: within one solve the stored frames stay put and the
energy is one smooth function of ``q``. Large motions are better taken in
steps, accepting each converged state (:meth:`System.accept`), so that the
frames follow the path; :func:`solve_incremental` does that, halving a step
that fails, and moves supports along :class:`~shellform.rods.node_path.NodePath`
paths.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from ..solvers.newton import StaticResult, solve_static


class SupportsAt:
    """A view of a System whose path-driven supports sit at their position for parameter ``t``.

    Every attribute is the System's, except :meth:`state`, which also sets the
    DOFs of the paths. Pass it to :func:`solve_static` in place of the System.
    """

    def __init__(self, system, paths: Sequence, t: float):
        self._system = system
        self._paths = tuple(paths)
        self.t = float(t)

    def state(self, u_free=None, mu: float = 0.0, base=None) -> np.ndarray:
        q = self._system.state(u_free, mu, base)
        for p in self._paths:
            q[p.dofs] = p(self.t)
        return q

    def __getattr__(self, name):
        return getattr(self._system, name)


def accept_state(system, q: np.ndarray) -> None:
    """Record ``q`` as accepted in every effect that keeps history (works on any System)."""
    hook = getattr(system, "accept", None)
    if hook is not None:
        hook(q)
        return
    for e in system.effects:
        h = getattr(e, "accept", None)
        if h is not None:
            h(q)


@dataclass
class IncrementalResult:
    """Outcome of :func:`solve_incremental`.

    Attributes
    ----------
    q : ndarray
        Last accepted state.
    success : bool
    message : str
    fractions : list of float
        Accepted values of the step parameter ``s`` in (0, 1].
    iterations : list of int
        Newton iterations of each accepted step.
    states : list of ndarray
        Accepted states (only when ``keep_states``).
    last : StaticResult
        Newton result of the last attempted step.
    wall_time_s : float
    """

    q: np.ndarray
    success: bool
    message: str
    fractions: list[float] = field(default_factory=list)
    iterations: list[int] = field(default_factory=list)
    states: list[np.ndarray] = field(default_factory=list)
    last: StaticResult | None = None
    wall_time_s: float = 0.0

    @property
    def n_steps(self) -> int:
        return len(self.fractions)


@dataclass(frozen=True)
class IncrementalOptions:
    """Step control of :func:`solve_incremental`.

    Attributes
    ----------
    n_steps : int
        Initial number of equal steps.
    min_fraction : float
        Smallest step, as a fraction of the whole ramp, before the solve gives up.
    keep_states : bool
        Keep every accepted state in the result.
    """

    n_steps: int = 10
    min_fraction: float = 1e-6
    keep_states: bool = False


def solve_incremental(
    system,
    lam: float = 1.0,
    mu: float = 0.0,
    *,
    q0: np.ndarray | None = None,
    paths: Sequence = (),
    t_end: float = 1.0,
    options: IncrementalOptions | None = None,
    callback: Callable[[float, StaticResult], None] | None = None,
    **overrides,
) -> IncrementalResult:
    """Equilibrium under a load ramped in steps: ``lam s``, ``mu s``, paths at ``t_end s``, ``s`` from 0 to 1.

    Each step starts from the last accepted state, is solved by
    :func:`~shellform.solvers.newton.solve_static` and, once converged,
    accepted by the System (rod frames transported). A failed step is
    halved, down to ``min_fraction``.

    Parameters
    ----------
    system : System
    lam, mu : float
        Final load factor and prescribed-displacement parameter.
    q0 : ndarray, optional
        State at ``s = 0`` (default the reference state).
    paths : sequence of NodePath
        Supports moved along paths, evaluated at ``t = t_end s``.
    options : IncrementalOptions, optional
        Step control (defaults: :class:`IncrementalOptions`).
    callback : callable, optional
        ``callback(s, result)`` after every accepted step.
    **overrides
        Any field of :class:`IncrementalOptions` by name (``n_steps``, ...);
        the others go to every Newton solve as its options by name
        (``rtol``, ``max_iter``, ...).
    """
    steps = {f.name for f in dataclasses.fields(IncrementalOptions)}
    o = dataclasses.replace(options or IncrementalOptions(), **{k: v for k, v in overrides.items() if k in steps})
    newton = {k: v for k, v in overrides.items() if k not in steps}
    t0 = time.perf_counter()
    q = system.state(base=q0) if q0 is None else np.array(q0, dtype=float)
    out = IncrementalResult(q=q, success=False, message="")
    s, ds = 0.0, 1.0 / max(int(o.n_steps), 1)
    while s < 1.0 - 1e-14:
        ds = min(ds, 1.0 - s)
        target = s + ds
        view = SupportsAt(system, paths, t_end * target) if paths else system
        res = solve_static(view, q0=q, lam=lam * target, mu=mu * target, **newton)
        out.last = res
        if res.success:
            q = res.q
            accept_state(system, q)
            s = target
            out.fractions.append(s)
            out.iterations.append(res.iterations)
            if o.keep_states:
                out.states.append(q.copy())
            if callback is not None:
                callback(s, res)
            # grow again after easy steps
            if res.iterations <= 4:
                ds *= 1.5
        else:
            ds *= 0.5
            if ds < o.min_fraction:
                out.q = q
                out.message = f"step from s = {s:.6g} failed even at increment {2 * ds:.3g}: {res.message}"
                out.wall_time_s = time.perf_counter() - t0
                return out
    out.q = q
    out.success = True
    out.message = f"reached s = 1 in {out.n_steps} steps"
    out.wall_time_s = time.perf_counter() - t0
    return out
