"""Apex indentation of the pre-stressed hemispherical gridshell (modes I and II).

The apex is pushed down by a prescribed displacement ``dD`` (the parameter
``mu`` of the System, direction ``-z``) and the equilibrium path is followed by
arc-length continuation in displacement control
(:func:`shellform.solvers.continuation.trace_path`):

* mode I ("simply supported"-like): the positions of the apex joint node(s)
  are prescribed, the rods may rotate freely about the apex;
* mode II ("clamped"-like): the apex and its neighbouring nodes along the two
  central rods (six nodes with penalty joints) move down together, so the
  rods' directions at the apex are held horizontal.

The indentation force is the reaction at the prescribed nodes, taken from
the residual: ``F = -sum(F_z)`` (positive when pushing down), reported also
as ``F R^2 / EI`` against ``dD / R`` as in the paper.

A quasi-static experiment in displacement control follows a stable branch
until it ends: at a limit point of ``dD`` (the path folds back) or at a
bifurcation where the branch loses stability. There the structure snaps to
another stable state at the same ``dD``. :func:`trace_indentation` does
exactly this: it traces the stable branch with arc-length continuation,
stops at the first point with a negative eigenvalue, locates the critical
point (the snapping threshold), then finds the stable state beyond it: the
critical state is pushed along its critical mode and carried downhill by
damped implicit Euler dynamics (the paper's own integrator) and Newton, and
the path continues from there. Small random dead forces (an imperfection)
break the symmetry of the net as in the paper; without them the symmetry is
broken only by the critical mode chosen at each snap.

A point is stable where a Cholesky factorisation of its tangent succeeds;
elsewhere the negative eigenvalues are counted from the pivot signs of an
LDL^T factorisation (:func:`~shellform.gridshell.snapping.negative_count`,
:func:`~shellform.solvers.stability.count_negative`), and critical modes come
from shift-invert Lanczos about zero
(:func:`~shellform.solvers.stability.smallest_eigenpair`): rod tangents in SI
units span twelve orders of magnitude. The way through a snap is in
:mod:`shellform.gridshell.snapping`, the naming of configurations in
:mod:`shellform.gridshell.configurations`.
"""

from __future__ import annotations

import copy
import dataclasses
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..assembly import System
from ..effects.loads import ConstantForce
from ..errors import ModelError
from ..solvers.continuation import trace_path
from .configurations import classify_configuration
from .hemisphere import HemisphereModel, PrestressResult
from .indentation_result import IndentationResult, Snap
from .snapping import SettleOptions, locate_stability_loss, lowest_mode, negative_count, settle

MODES = ("I", "II")


@dataclass
class IndentationSetup:
    """The indentation problem: a System whose prescribed DOFs are the apex nodes.

    Attributes
    ----------
    system : System
        Rod effects of the model (sharing its reference frames), the
        imperfection forces, constraints of the pinned ends plus the
        prescribed nodes; ``q_ref`` is the pre-stressed state, so
        ``mu = dD``.
    mode : {"I", "II"}
    nodes : ndarray
        Prescribed nodes (moved down by ``dD``).
    z_dofs : ndarray
        Their vertical DOFs (the indentation force is minus the sum of the
        reactions there).
    force_scale : float
        ``EI / R^2`` [N].
    imperfection : ndarray (n_dof,)
        The dead forces that break the symmetry.
    """

    model: HemisphereModel
    system: System
    mode: str
    nodes: np.ndarray
    z_dofs: np.ndarray
    force_scale: float
    imperfection: np.ndarray
    frames_state: dict

    def force(self, q: np.ndarray) -> float:
        """Indentation force ``-sum(F_z)`` at the prescribed nodes [N]."""
        r = self.system.residual(q, 1.0)
        return -float(r[self.z_dofs].sum())


def indentation_system(
    model: HemisphereModel,
    prestress: PrestressResult,
    mode: str = "I",
    imperfection: float = 1.0e-4,
    seed: int = 0,
) -> IndentationSetup:
    """The apex-indentation problem of a pre-stressed hemisphere.

    Parameters
    ----------
    model : HemisphereModel
    prestress : PrestressResult
        The pre-stressed state (its System's rod frames are the model's).
    mode : {"I", "II"}
        Apex node(s) only, or apex and neighbours (clamped-like).
    imperfection : float
        Norm of the random dead forces on the free node translations, as a
        fraction of ``EI / R^2``; 0 for a perfect structure.
    seed : int
        Seed of the random imperfection.
    """
    if mode not in MODES:
        raise ModelError(f"indentation: mode must be one of {MODES}, got {mode!r}")
    if not (np.isfinite(imperfection) and imperfection >= 0):
        raise ModelError(f"indentation: imperfection must be non-negative, got {imperfection}")
    nodes = model.apex_nodes if mode == "I" else np.concatenate([model.apex_nodes, model.apex_neighbours()])
    # the model's structure stays as it is (both modes can be run on one model);
    # the indentation system gets its own copy of the constraints
    structure = copy.deepcopy(model.structure)
    structure.prescribe(nodes, [0.0, 0.0, -1.0])
    effects = model.network.effects()
    f = np.zeros(structure.n_dof)
    scale = model.EI / model.radius**2
    if imperfection > 0:
        rng = np.random.default_rng(seed)
        free_nodes = ~structure.constrained_mask[: 3 * structure.n_nodes]
        g = rng.normal(size=3 * structure.n_nodes) * free_nodes
        f[: 3 * structure.n_nodes] = imperfection * scale * g / np.linalg.norm(g)
        effects.append(ConstantForce(f, scales_with_load=False, name="imperfection"))
    system = System(structure, effects, check=False)
    # the pre-stressed state is the reference: mu is the apex displacement dD
    system.q_ref = np.array(prestress.q, dtype=float)
    z_dofs = 3 * nodes + 2
    frames = prestress.frames if prestress.frames else model.network.frames.state()
    return IndentationSetup(model, system, mode, nodes, z_dofs, scale, f, frames)


@dataclass(frozen=True)
class IndentationOptions:
    """How :func:`trace_indentation` follows the path and passes its snaps.

    Attributes
    ----------
    dD_max : float, optional
        Final apex displacement [m]; default ``2 R``.
    increment : float
        First step of the continuation, as apex displacement over ``R``.
    snap_offset : float
        Where the branch ends, the stable state beyond it is sought at
        ``dD_c + snap_offset R``.
    push : float
        Size of the push along the critical mode that starts the snap (largest
        node displacement, relative to ``R``).
    min_jump : float
        A loss of stability counts as a snap when some node moves further
        than ``min_jump R`` to the next stable state; below that the path
        simply continues on the stable branch that crosses there (a
        supercritical bifurcation), recorded in ``exchanges``.
    merge_within : float
        A snap that lands in a state which loses stability again within
        ``merge_within R`` of further indentation is merged with the next one
        (a dynamic experiment passes through such a state without stopping);
        ``Snap.merged`` counts the merges.
    locate_tol : float
        Accuracy in ``dD / R`` to which a bifurcation is located.
    max_snaps : int
        Stop after this many losses of stability.
    max_steps : int
        Continuation steps in all.
    rtol : float
        Relative tolerance of the continuation's corrector.
    snap_method : {"dynamic", "energy", "auto"}
        How the stable state after a critical point is found: damped
        implicit Euler dynamics then Newton (the paper's physics), a pure
        energy descent (it can creep along flat valleys), or the descent
        first and the dynamics when it stalls.
    snap_time_step, snap_damping : float
        Time step [s] and mass-proportional damping [1/s] of the dynamics
        through a snap (with a 1 ms step the scheme itself dissipates most
        of the motion, so the damping hardly changes where a snap lands).
    min_drop : float
        A loss of stability counts as a snap only when the force also changes
        by at least this fraction.
    classify : bool
        Label every point's configuration.
    store_states : bool
        Keep the state of every path point (``result.path_states``).
    """

    dD_max: float | None = None
    increment: float = 0.01
    snap_offset: float = 2.0e-3
    push: float = 2.0e-2
    min_jump: float = 0.03
    merge_within: float = 0.01
    locate_tol: float = 5.0e-4
    max_snaps: int = 12
    max_steps: int = 3000
    rtol: float = 1e-9
    snap_method: str = "dynamic"
    snap_time_step: float = 1.0e-3
    snap_damping: float = 100.0
    min_drop: float = 0.05
    classify: bool = True
    store_states: bool = False


class _Trace:
    """The path of one indentation run as it grows: points, snaps, states and counters."""

    def __init__(self, setup: IndentationSetup, o: IndentationOptions, progress):
        self.setup, self.o, self.progress = setup, o, progress
        self.model, self.system = setup.model, setup.system
        self.R = self.model.radius
        self.dD_max = 2.0 * self.R if o.dD_max is None else float(o.dD_max)
        self.xs, self.fs, self.seg, self.negs, self.labels = [], [], [], [], []
        self.path_states: list[np.ndarray] = []
        self.snaps: list[Snap] = []
        self.exchanges: list[Snap] = []
        self.states: dict[float, np.ndarray] = {}
        self.state_histories: dict[float, tuple | None] = {}  # the rod frames each state was found with
        self.path_histories: list = []
        self.totals = {"steps": 0, "newton": 0, "rejected": 0}
        self.timings: dict[str, float] = {"stability": 0.0}
        self.q, self.p, self.segment = np.array(self.system.q_ref), 0.0, 0
        self.segment_start, self.snap_start_q = None, None

    def add_point(self, qq, mu, n_neg):
        self.xs.append(mu)
        self.fs.append(self.setup.force(qq))
        self.seg.append(self.segment)
        self.negs.append(n_neg)
        self.labels.append(classify_configuration(self.model, qq) if self.o.classify else "")
        if self.o.store_states:
            self.path_states.append(np.array(qq))
            self.path_histories.append(self.system.history())
        if self.progress is not None:
            self.progress(mu / self.R, self.fs[-1] / self.setup.force_scale, n_neg)

    def trace_branch(self):
        """Follow the stable branch from the current state to its first unstable point (or the end)."""
        last = {}
        system = self.system

        def on_point(pt):
            # carry the rod frames along the path; stop at the first unstable point
            system.accept(pt.q)
            n_neg = pt.n_negative
            if n_neg != 0:
                # not proven stable by the tracer's Cholesky factor of the point's tangent. That tangent
                # was taken with the rod frames before they were accepted here (at an equilibrium the two
                # parametrisations give congruent tangents, of the same inertia), and may be the
                # corrector's last, a last correction away: only a critical point within that distance
                # could be passed by one point, and is then located next to it
                ts = time.perf_counter()
                n_neg = negative_count(self.setup, system.tangent_free(pt.q))
                self.timings["stability"] += time.perf_counter() - ts
            if n_neg != 0:
                last["unstable"] = (pt.mu, pt.q.copy(), n_neg)
                return True
            if not (pt.step == 0 and self.xs and abs(pt.mu - self.xs[-1]) < 1e-15 and self.segment == self.seg[-1]):
                self.add_point(pt.q, pt.mu, 0)
            last["stable"] = (pt.mu, pt.q.copy(), system.history())
            return None

        res = trace_path(
            system, "displacement", q0=self.q, p0=self.p, callback=on_point,
            initial_increment=self.o.increment * self.R, parameter_bounds=(-np.inf, self.dD_max),
            max_steps=self.o.max_steps - self.totals["steps"], rtol=self.o.rtol, store_states=False,
            stability=False, definite_branch=True, locate_tol=1e-2,
        )
        self.totals["steps"] += res.steps
        self.totals["newton"] += res.newton_iterations
        self.totals["rejected"] += res.rejected_steps
        for k, v in res.timings.items():
            self.timings[k] = self.timings.get(k, 0.0) + v
        if "stable" in last:
            self.keep_state(*last["stable"])
        return res, last

    def critical_point(self, res, last):
        """Where the branch ends: a fold of dD located by the tracer, or a bifurcation located here.

        Returns ``(mu, q, kind, located, mode, history)``, ``history`` the rod frames ``q`` was found with.
        """
        system = self.system
        folds = [e for e in res.events if e.kind == "limit" and e.step == res.steps]
        mu_a, q_a, h_a = last["stable"]
        mu_b, q_b, _ = last["unstable"]
        if folds and folds[-1].located:
            ev = folds[-1]
            history = ev.history if ev.history is not None else system.history()
            return ev.mu, ev.q, "limit", True, lowest_mode(system.tangent_free(ev.q)), history
        if mu_b > mu_a:
            mu_c, q_c, located = locate_stability_loss(self.setup, q_a, mu_a, q_b, mu_b, self.o.locate_tol * self.R)
            return mu_c, q_c, "bifurcation", located, lowest_mode(system.tangent_free(q_c)), system.history()
        return mu_a, q_a, "unlocated", False, lowest_mode(system.tangent_free(q_b)), h_a

    def beyond(self, mu_c, q_c, mode_free):
        """The stable state past the critical point: ``(q, mu, why)``, ``q`` None when none was found.

        Next to a supercritical bifurcation it is itself nearly critical and
        Newton crawls, so a failure is retried a little further on (with the rod
        frames of the critical state).
        """
        o = self.o
        how = SettleOptions(o.push, method=o.snap_method, time_step=o.snap_time_step, damping=o.snap_damping)
        frames = self.model.network.frames.state()
        for factor in (1.0, 4.0, 16.0):
            self.model.network.frames.restore(frames)
            mu_new = min(mu_c + factor * o.snap_offset * self.R, self.dD_max)
            q_new, its, why = settle(self.setup, q_c, mu_new, mode_free, how)
            self.totals["newton"] += its
            if q_new is not None:
                return q_new, mu_new, why
        return None, mu_new, why

    def keep_state(self, mu, q, history):
        """Keep ``q`` (at ``dD = mu``) among the selected states, with the rod frames it was found with."""
        self.states[mu / self.R] = q
        self.state_histories[mu / self.R] = history

    def record_snap(self, mu_c, q_c, f_c, h_c, kind, located, q_new, mu_new):
        """Record what happened at the critical point: a snap, a merged snap or an exchange of stability.

        ``f_c`` is the force at the critical state ``q_c`` and ``h_c`` the rod frames it was found with,
        both taken before the snap moved the frames.
        """
        o, setup, model = self.o, self.setup, self.model
        x_c, x_new = model.positions(q_c), model.positions(q_new)
        jump = float(np.abs(x_new - x_c).max() / self.R)
        before = classify_configuration(model, q_c) if o.classify else ""
        event = Snap(mu_c, mu_c / self.R, f_c / setup.force_scale, setup.force(q_new) / setup.force_scale, kind,
                     located, before, "", jump)
        f_new = setup.force(q_new)
        if abs(f_new - f_c) < o.min_drop * max(abs(f_c), 1e-3 * setup.force_scale):
            jump = min(jump, 0.0)  # no force drop: the path goes on smoothly, not a snap
        if (jump >= o.min_jump and self.snaps and self.segment_start is not None
                and mu_c - self.segment_start < o.merge_within * self.R):
            # the state a snap landed in is lost again right away: in a dynamic
            # experiment this is one snap, so merge it into the previous one
            keep = [i for i, s in enumerate(self.seg) if s != self.segment]
            for lst in (self.xs, self.fs, self.seg, self.negs, self.labels) + (
                    (self.path_states, self.path_histories) if o.store_states else ()):
                lst[:] = [lst[i] for i in keep]
            event = self.snaps[-1]
            event.force_after = setup.force(q_new) / setup.force_scale
            event.jump = float(np.abs(x_new - model.positions(self.snap_start_q)).max() / self.R)
            event.merged += 1
        elif jump >= o.min_jump:
            self.segment += 1
            self.keep_state(mu_c, np.array(q_c), h_c)
            self.snaps.append(event)
            self.snap_start_q = np.array(q_c)
        else:
            self.exchanges.append(event)
        self.add_point(q_new, mu_new, 0)
        event.label_after = self.labels[-1]
        self.keep_state(mu_new, q_new.copy(), self.system.history())
        self.segment_start = mu_new if jump >= o.min_jump else self.segment_start
        self.q, self.p = q_new, mu_new

    def run(self) -> tuple[bool, str]:
        """Trace branches and pass snaps until the end; ``(success, message)``."""
        losses = 0
        while True:
            res, last = self.trace_branch()
            here = self.xs[-1] / self.R if self.xs else 0.0
            if res.status == "parameter_bound" or (res.status == "callback" and "unstable" not in last):
                return True, f"reached dD/R = {here:.4g}"
            if res.status != "callback":
                return False, f"continuation ended at dD/R = {here:.4g}: {res.message}"
            if "stable" not in last:
                return False, f"the starting state at dD/R = {self.p / self.R:.4g} is unstable"
            losses += 1
            if losses > self.o.max_snaps:
                return True, f"stopped after {self.o.max_snaps} losses of stability at dD/R = {last['stable'][0] / self.R:.4g}"
            mu_c, q_c, kind, located, mode_free, h_c = self.critical_point(res, last)
            # the rods' twist angles are measured from reference frames carried along the path: the
            # critical state's force is read with the frames it was found with, not those the snap
            # leaves (with which the same state vector describes other twists, other forces)
            with self.system.evaluated_with(h_c):
                f_c = self.setup.force(q_c)
            q_new, mu_new, why = self.beyond(mu_c, q_c, mode_free)
            if q_new is None:
                return False, f"no stable state found beyond the critical point at dD/R = {mu_c / self.R:.4g}: {why}"
            self.system.accept(q_new)
            self.record_snap(mu_c, q_c, f_c, h_c, kind, located, q_new, mu_new)
            if mu_new >= self.dD_max:
                return True, f"reached dD/R = {mu_new / self.R:.4g}"


def trace_indentation(
    setup: IndentationSetup,
    options: IndentationOptions | None = None,
    progress: Callable[[float, float, int], None] | None = None,
    **overrides,
) -> IndentationResult:
    """Trace the indentation from ``dD = 0`` to ``dD_max`` through every snap.

    Parameters
    ----------
    setup : IndentationSetup
    options : IndentationOptions, optional
        How the path is followed (defaults: :class:`IndentationOptions`).
    progress : callable, optional
        ``progress(dD / R, force / (EI / R^2), n_negative)`` after every point.
    **overrides
        Any field of :class:`IndentationOptions` by name, on top of ``options``.
    """
    names = {f.name for f in dataclasses.fields(IndentationOptions)}
    if set(overrides) - names:
        raise TypeError(f"unknown indentation option(s): {sorted(set(overrides) - names)}")
    o = dataclasses.replace(options or IndentationOptions(), **overrides)
    t0 = time.perf_counter()
    setup.model.network.frames.restore(setup.frames_state)
    tr = _Trace(setup, o, progress)
    success, message = tr.run()
    tr.timings["total"] = time.perf_counter() - t0
    return IndentationResult(
        mode=setup.mode, radius=tr.R, force_scale=setup.force_scale, dD=np.asarray(tr.xs), force=np.asarray(tr.fs),
        segment=np.asarray(tr.seg, dtype=int), n_negative=np.asarray(tr.negs, dtype=int), snaps=tr.snaps,
        labels=tr.labels, states=tr.states, success=success, message=message,
        steps=tr.totals["steps"], newton_iterations=tr.totals["newton"], rejected_steps=tr.totals["rejected"],
        n_dof=setup.system.n_dof, n_free=setup.system.n_free, wall_time_s=time.perf_counter() - t0,
        timings=tr.timings, exchanges=tr.exchanges, path_states=tr.path_states,
        state_histories=tr.state_histories, path_histories=tr.path_histories,
    )
