"""The implicit scheme: pseudo-transient continuation through stiffness stages.

Each step is a backward-Euler step of the motion from rest,
``(K + (1/h^2 + c/h) M) dq = -r``, with the global sparse tangent
``System.tangent_free``. The total potential of a hanging net is convex, so a
step is accepted when the potential falls as the step's model predicts, and
the pseudo time step ``h`` grows; when it grows without bound the step is
Newton's. :func:`run_implicit` runs one :func:`pseudo_transient` stage per
stiffness scale (:mod:`.stiffness`); the run's counters and the tangent's
diagonal positions carry over in :class:`Stages`, a stage's state lives in
:class:`StepState`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ..linear import SingularMatrixError
from .active_set import SlackRopeModel, engage_slack_ropes
from .force_density import force_density_start
from .line_search import energy_change, line_search, sufficient_decrease
from .linalg import SPDSolve, diagonal_positions, with_values
from .monitor import Measures, Monitor, converged_message, limit_message
from .options import RelaxationOptions
from .patch import NodeGraph, patchable
from .patch_steps import PatchContext, repair_full_step, sweep_fronts
from .ropes import rope_effects, switch_model_change
from .stiffness import STAGE_TOLERANCE, continuation_scales, with_stiffness_scale

#: rejected pseudo steps in a row after which a stage gives up (the net may be a mechanism)
MAX_REJECTED = 60


@dataclass
class Stages:
    """What carries over from one stiffness stage to the next."""

    iterations: int = 0
    time: float = 0.0
    #: index into the tangent's values of its diagonal (the pattern is fixed for the run)
    diagonal: np.ndarray | None = None


@dataclass
class StageEnd:
    """How a stage ended: its last state and status."""

    q: np.ndarray
    h: float
    v: np.ndarray
    success: bool
    message: str
    vmax: float
    amax: float
    rnorm: float


@dataclass
class Stage:
    """What stays fixed during one stage: its System, solver, tolerances and scales."""

    system: object
    mon: Monitor
    solver: SPDSolve
    lam: float
    a_tol: float
    v_tol: float
    max_it: int
    ropes: list  # tension-only members whose slack state the step's model takes into account
    graph: NodeGraph | None  # the net's node graph, where a refinement works on patches
    settling: bool
    sweeps: bool
    repair: bool
    f_ext: np.ndarray
    f_scale: float
    e_floor: float  # changes of the potential below this are round-off
    h_max: float

    def residual(self, q: np.ndarray) -> np.ndarray:
        self.mon.n_res += 1
        return self.system.residual(q, self.lam)[self.system.free]

    def slack_model(self) -> SlackRopeModel:
        """The stage's ropes for the active set, settled on patches where the stage settles."""
        return SlackRopeModel(self.system, self.ropes, graph=self.graph if self.settling else None)

    def patches(self) -> PatchContext:
        """What the stage's front sweeps and step repairs share."""
        st = self.mon.st
        return PatchContext(self.system, self.graph, st.m, st.damping, self.f_ext, self.e_floor, self.ropes)


@dataclass
class StepState:
    """The state of a stage between two steps."""

    q: np.ndarray
    h: float
    r: np.ndarray
    v: np.ndarray
    vmax: float
    amax: float
    rnorm: float
    K: sp.csr_matrix | None = None  # the tangent at q, once assembled
    engaged: list | None = None  # the last step's set of engaged slack ropes
    tries: int = 0  # pseudo steps rejected in a row

    def end(self, success: bool, message: str, measured: bool = True) -> StageEnd:
        if not measured:
            return StageEnd(self.q, self.h, self.v, success, message, np.nan, np.nan, np.nan)
        return StageEnd(self.q, self.h, self.v, success, message, self.vmax, self.amax, self.rnorm)


def run_implicit(system, st, options: RelaxationOptions, callback, t0, fd_start=False):
    """Relax ``system`` from ``st`` by pseudo-transient continuation through the stiffness stages."""
    ref, lam = options.refinements, options.lam
    mon = Monitor(system, st, "implicit", lam, callback, options.report_every, t0, options.max_wall_time)
    graph = NodeGraph(system) if ref.on_patches and patchable(system) else None
    free = system.free
    solver = SPDSolve(options.linear_solver, free.size, coords=st.q, dofs=free, correct=ref.factor_correction)
    scales = continuation_scales(system, st, lam)
    if fd_start:
        # the force-density shape in balance with the first stage's stiffness: the softest
        # stage then starts near its equilibrium instead of falling from the planform
        q_fd = force_density_start(system, lam, scales[0], base=st.q)
        if q_fd is not None:
            st.q, st.start = q_fd, "force_density"
    # the first pseudo step is a free fall of about 1 % of the net's size
    h = float(options.dt) if options.dt is not None else np.sqrt(0.02 * st.L_ref / st.g_ref)
    q = st.q.copy()
    run = Stages()
    for k, scale in enumerate(scales):
        last = k == len(scales) - 1
        view = system if scale == 1.0 else with_stiffness_scale(system, scale)
        stage = _stage(view, mon, solver, q, options, graph, last)
        out = pseudo_transient(stage, q, h, run)
        q, h = out.q, out.h
        mon.n_fact = solver.factorizations
        mon.n_cg = solver.cg_iterations
        mon.n_corrected = solver.corrected
        if not out.success or last:
            message = out.message
            if not last:
                message = f"stiffness stage {k + 1} of {len(scales)} (EA x {scale:.1e}): {message}"
            return mon.finish(q[free], out.v, out.success, message, run.iterations, run.time, h,
                              Measures(out.vmax, out.amax, out.rnorm))
        # a stiffer net moves little from here: restart with a moderate pseudo step
        h = min(h, np.sqrt(st.L_ref / st.g_ref))


def _stage(system, mon, solver, q, options, graph, last: bool) -> Stage:
    """The fixed parts of a stage on ``system`` (one stiffness scale) starting at ``q``; the ``last``
    stage is the unscaled net."""
    st, ref, lam = mon.st, options.refinements, options.lam
    # intermediate stages only need to land near their equilibrium
    a_tol = st.a_tol if last else max(st.a_tol, STAGE_TOLERANCE * st.g_ref)
    v_tol = st.v_tol if last else np.inf
    f_ext = system.external_force(lam)
    stage = Stage(system=system, mon=mon, solver=solver, lam=lam, a_tol=a_tol, v_tol=v_tol,
                  max_it=options.iteration_limit, ropes=rope_effects(system) if ref.slack_active_set else [],
                  graph=graph, settling=ref.slack_settling, sweeps=ref.front_sweeps, repair=ref.step_repair,
                  f_ext=f_ext, f_scale=0.0,  # set from the first residual of the stage
                  # work of the loads over one ulp of the positions
                  e_floor=1e3 * np.finfo(float).eps * float(np.abs(f_ext).sum())
                  * max(st.L_ref, float(np.abs(q).max())),
                  h_max=1e12 * np.sqrt(st.L_ref / st.g_ref))
    return stage


def pseudo_transient(stage: Stage, q: np.ndarray, h: float, run: Stages) -> StageEnd:
    """Pseudo-transient continuation on one stage's System; returns its final state and status."""
    mon = stage.mon
    r = stage.residual(q)
    v = np.zeros(stage.system.free.size)
    s = StepState(q, h, r, v, *mon.measure(v, r))
    stage.f_scale = max(float(np.linalg.norm(stage.f_ext[stage.system.free])), s.rnorm, 1e-300)
    while True:
        end = _stopped(stage, s, run)
        if end is not None:
            return end
        direction = _direction(stage, s, run)
        taken = None if direction is None else _advance(stage, s, *direction)
        if taken is None:
            mon.rejected += 1
            s.h *= 0.25
            s.tries += 1
            continue
        _accept(stage, s, run, taken)
        s.vmax, s.amax, s.rnorm = mon.measure(s.v, s.r)
        stop = mon.tick(run.iterations, run.time, s.vmax, s.amax, s.rnorm, s.q[stage.system.free], s.v)
        if stop:
            return s.end(False, stop)


def _stopped(stage: Stage, s: StepState, run: Stages) -> StageEnd | None:
    """The end of the stage, if it has come: failure, rest, or a limit."""
    if not np.isfinite(s.rnorm):
        return s.end(False, f"the residual is not finite at iteration {run.iterations}", measured=False)
    if s.vmax <= stage.v_tol and s.amax <= stage.a_tol:
        return s.end(True, converged_message(stage.mon, run.iterations, s.vmax, s.amax))
    if run.iterations >= stage.max_it:
        return s.end(False, limit_message(stage.mon, run.iterations, s.vmax, s.amax))
    if s.tries > MAX_REJECTED:
        return s.end(False, f"iteration {run.iterations}: no pseudo time step reduced the potential "
                            f"(last step {s.h:.3e} s); the net may be a mechanism")
    return None


def _direction(stage: Stage, s: StepState, run: Stages):
    """``(p, slope, predicted change)`` of the pseudo step from ``s``, or None when it is no descent."""
    system, st = stage.system, stage.mon.st
    if s.K is None:
        s.K = system.tangent_free(s.q)
        s.K.sort_indices()
        if run.diagonal is None:
            run.diagonal = diagonal_positions(s.K)
    # backward-Euler step from rest with viscous damping: (M/h^2 + C/h + K) dq = -r
    A = with_values(s.K, s.K.data.copy())
    A.data[run.diagonal] += (1.0 / s.h**2 + st.damping / s.h) * st.m
    # inexact steps far from equilibrium, accurate ones close to it
    eta = min(1e-2, max(1e-10, float(np.sqrt(s.rnorm / stage.f_scale))))
    try:
        if stage.ropes:
            p, s.engaged = engage_slack_ropes(stage.slack_model(), stage.solver, A, s.r, s.q, eta, s.engaged)
        else:
            p = stage.solver.solve(A, -s.r, eta)
    except SingularMatrixError:
        return None
    slope = float(s.r @ p)
    if not slope < 0:
        return None
    pred = slope + 0.5 * float(p @ (s.K @ p))
    if stage.ropes:
        # the step was solved in the ropes' piecewise model, not the tangent's: judged
        # against the tangent alone, a step that lets taut ropes go slack seems to
        # predict a rise, and the pseudo step was held for many steps at 4e5 nodes
        dq = np.zeros(system.n_dof)
        dq[system.free] = p
        pred += sum(float(switch_model_change(e, s.q, dq).sum()) for e in stage.ropes)
    return p, slope, pred


@dataclass
class Taken:
    """A step along ``p`` that lowers the potential: its length, new state and residual."""

    alpha: float
    q: np.ndarray
    r: np.ndarray
    rho: float  # the achieved over the predicted change of the potential
    tiny: bool  # the predicted change is round-off
    p: np.ndarray


def _advance(stage: Stage, s: StepState, p, slope, pred) -> Taken | None:
    """The step along ``p``, repaired or line-searched; None when no length lowers the potential."""
    system, mon = stage.system, stage.mon
    free, q = system.free, s.q
    tiny = abs(pred) <= stage.e_floor

    def at(a, p=p):
        qq = q.copy()
        qq[free] += a * p
        rr = stage.residual(qq)
        return energy_change(system, q, qq, stage.lam), rr, float(rr @ p)

    first = at(1.0)
    dE1, r1, d1 = first
    repaired = None
    # only a full step that the line search would cut
    if stage.repair and stage.graph is not None and stage.ropes and not tiny and np.all(np.isfinite(r1)) \
            and np.isfinite(dE1) and not sufficient_decrease(dE1, d1, slope):
        repaired = repair_full_step(stage.patches(), q, p, r1, dE1, slope, s.h)
    if repaired is not None:
        q_new, r_try, dE, excess = repaired
        mon.n_repaired += 1
        # outside the patch the step followed its model
        return Taken(1.0, q_new, r_try, (dE1 - excess) / pred if pred < 0 else 0.5, tiny, p)
    alpha, dE, r_try = line_search(at, slope, s.rnorm, tiny, first=first)
    if alpha == 0.0:
        return None
    q_new = q.copy()
    q_new[free] += alpha * p
    return Taken(alpha, q_new, r_try, dE / pred if (pred < 0 and alpha == 1.0) else 0.5, tiny, p)


def _accept(stage: Stage, s: StepState, run: Stages, step: Taken) -> None:
    """Move ``s`` to the accepted step, adapt the pseudo step and sweep the fronts."""
    alpha, rho, tiny = step.alpha, step.rho, step.tiny
    s.tries = 0
    s.v = alpha * step.p / s.h
    s.q, s.r, s.K = step.q, step.r, None
    run.time += s.h
    run.iterations += 1
    if alpha == 1.0 and (rho > 0.75 or tiny):
        s.h = min(4.0 * s.h, stage.h_max)
    elif alpha < 0.1:
        s.h *= 0.25
    elif rho < 0.25:
        # a partial step is progress; only a poor quadratic model shortens the pseudo step
        s.h *= 0.5
    if stage.graph is not None and stage.sweeps:
        stage.mon.n_local += sweep_fronts(stage.patches(), s.q, s.r, s.h, stage.a_tol)
