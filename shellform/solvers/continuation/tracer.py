"""The tracer: the state of a path being traced and the loop that extends it.

Each step predicts along the path tangent ``t = (du/dp, 1)``, oriented so that it
keeps the direction of travel, corrects onto the path
(:mod:`~shellform.solvers.continuation.corrector`), counts the negative
eigenvalues of the tangent and, where the step changed the sign of ``dp/ds`` or
that count, locates the critical point inside it
(:mod:`~shellform.solvers.continuation.events`). Step lengths adapt to the
corrector's iterations and are bounded by what the structure can do
(:mod:`shellform.solvers.step_bounds`).
"""

from __future__ import annotations

import math
import time

import numpy as np

from ...errors import ModelError
from ..linear import CholeskyFactor, LDLFactor, SingularMatrixError
from ..mechanism import describe_soft_modes
from ..raised_cholesky import RaisedCholeskyFactor
from ..stability import DENSE_LIMIT, InertiaError, inertia, nearest_eigenvalue
from ..step_bounds import FOLD_OVERSHOOT, fold_distance
from .branches import switch_at
from .corrector import StepPoint, correct, equilibrium, land, point_linearisation
from .events import locate
from .options import CONTROLS, ContinuationOptions
from .problem import LocationFailure, Problem, StepFailure, Timer
from .results import TABLE_COLUMNS, ContinuationResult, PathEvent, PathPoint
from .snapshot import Checkpoint, save


class Tracer:
    """The state of one path being traced, and the loop that extends it step by step.

    Parameters
    ----------
    system : System
    control : {"load", "displacement"}
    options : ContinuationOptions
    """

    def __init__(self, system, control: str, options: ContinuationOptions):
        if control not in CONTROLS:
            raise ValueError(f"control must be one of {CONTROLS}, got {control!r}")
        o = options
        self.system = system
        self.control = control
        self.o = o
        self.timer = Timer()
        self.t_created = time.perf_counter()
        self.pb = Problem(system, control, o.fixed_lam, o.fixed_mu, self.timer, o.linear_solver)
        # Cholesky first while the path is stable (and at the start, before anything is counted):
        # where it succeeds there is no negative eigenvalue
        self.pb.expected_negative = lambda: (getattr(self, "n_neg", 0) if self.o.stability
                                             else (0 if self.o.definite_branch else -1))
        self.pb.soft_direction = lambda: getattr(self, "t_du", None)
        #: ``(u, K, g, F)`` of the last point analysed: what follows it (event location) reuses them
        self.last_linearisation = None
        self.corrector_last = None  # the corrector's last linearisation (corrector.LastLinearisation)
        self.free = system.free
        self.monitors = dict(o.monitors or {})
        for name, spec in self.monitors.items():
            if not callable(spec):
                i = int(spec)
                if not 0 <= i < system.n_dof:
                    raise ModelError(f"monitor {name!r}: DOF index {i} out of range 0..{system.n_dof - 1}")
        # displacement measure
        if control == "displacement":
            self.disp_dof = None
        else:
            dof = o.displacement_dof
            if dof is None:
                dof = int(np.argmax(np.abs(self.pb.f_ref)))
            self.disp_dof = int(dof)
            s = np.sign(self.pb.f_ref[self.disp_dof])
            self.disp_sign = float(s) if s != 0 else 1.0
        self.table = {c: [] for c in TABLE_COLUMNS}
        for name in self.extra_columns():
            if name in self.table:
                raise ModelError(f"monitor name {name!r} clashes with a path table column")
            self.table[name] = []
        self.states: list[np.ndarray] = []
        self.state_steps: list[int] = []
        self.state_histories: list = []  # the rod frames each state was found with
        self.events: list[PathEvent] = []
        self.rejected = 0
        self.newton_total = 0
        self.switches = 0
        self.finished = None  # (status, message, success) once a run has ended
        self.play = None  # forces in play at the last accepted point, computed when first needed

    # -- metric -----------------------------------------------------------------------
    def dot(self, du1, dp1, du2, dp2):
        return float(du1 @ du2) + self.c2 * dp1 * dp2

    def norm(self, du, dp):
        return math.sqrt(max(self.dot(du, dp, du, dp), 0.0))

    # -- measures -------------------------------------------------------------------------
    def location(self, q, r, p, arc_length) -> dict:
        """The :class:`PathLocation` fields of state ``q`` (residual ``r``) at parameter ``p``."""
        lam, mu = self.pb.lam_mu(p)
        return dict(
            arc_length=arc_length, lam=lam, mu=mu, parameter=float(p),
            load=self.pb.load_measure(r, p), displacement=self.displacement_measure(q, p),
        )

    def displacement_measure(self, q, p):
        if self.control == "displacement":
            return float(p)
        i = self.disp_dof
        return self.disp_sign * float(q[i] - self.system.q_ref[i])

    def extra_columns(self) -> list[str]:
        """The table's columns beyond ``TABLE_COLUMNS``: the monitors, then the eigenvalue when asked for."""
        return list(self.monitors) + (["eigenvalue"] if self.o.eigenvalue_column else [])

    def monitor_values(self, q, p):
        lam, mu = self.pb.lam_mu(p)
        out = {"eigenvalue": self.nearest_eigenvalue(q, p)} if self.o.eigenvalue_column else {}
        for name, spec in self.monitors.items():
            if callable(spec):
                out[name] = float(spec(q, lam, mu))
            else:
                i = int(spec)
                out[name] = float(q[i] - self.system.q_ref[i])
        return out

    def nearest_eigenvalue(self, q, p) -> float:
        """The eigenvalue of the free tangent nearest zero at the point ``q``, with the point's own factor."""
        t0 = time.perf_counter()
        try:
            lin = self.last_linearisation
            u = q[self.free]
            if lin is not None and np.array_equal(lin[0], u) and lin[3] is not None:
                K, F = lin[1], lin[3]
            else:
                K, _ = self.pb.jacobian(u, p, q)
                F = self.pb.factor(K)
            value = nearest_eigenvalue(K, F)
            if np.isnan(value) and K.shape[0] > DENSE_LIMIT:
                # the point's factor may have lent its storage to a later one (event location): a fresh one
                try:
                    value = nearest_eigenvalue(K, LDLFactor(K))
                except SingularMatrixError:
                    pass
            return value
        finally:
            self.timer.add("stability", t0)

    # -- linearisation at a converged point ------------------------------------------------
    def analyse_point(self, u, p, ref_du, ref_dp, q=None):
        """Tangent (oriented along ``ref``) and inertia at a converged point."""
        if self.o.stability:
            # the count decides whether a critical point lies in the step: the point's own tangent
            K, g = self.pb.jacobian(u, p, q)
            F = self.pb.factor(K)
        else:
            K, g, F = point_linearisation(self, u, p, q, self.norm(ref_du, ref_dp))
        t_du, t_dp = self.tangent_from(K, g, F, ref_du, ref_dp)
        n_neg = self.count(K, F)
        self.last_linearisation = (u, K, g, F)
        return t_du, t_dp, n_neg, K

    def tangent_from(self, K, g, F, ref_du, ref_dp):
        du = None
        if F is not None:
            try:
                du = self.pb.solve(F, -g)
                dp = 1.0
            except SingularMatrixError:
                du = None
        if du is None:
            if ref_du is None:
                raise SingularMatrixError("the tangent is singular at the starting point and there is no direction of travel")
            du, dp = self.pb.bordered_solve(K, g, ref_du, self.c2 * ref_dp, np.zeros(K.shape[0]), 1.0, F)
        nrm = self.norm(du, dp)
        if not np.isfinite(nrm) or nrm == 0.0:
            raise SingularMatrixError("the path tangent has zero length in the arc-length metric")
        du, dp = du / nrm, dp / nrm
        if ref_du is not None and self.dot(du, dp, ref_du, ref_dp) < 0.0:
            du, dp = -du, -dp
        return du, dp

    def count(self, K, F=None, signed=False):
        """Negative eigenvalues of ``K``: beyond the zero tolerance, or (``signed``) of any size.

        -1 when not counted: without ``stability`` only a Cholesky factor ``F``
        gives a count (none, proven by the factor existing).

        Along the path a tiny eigenvalue counts as zero so that rounding noise
        next to a critical point is not reported as an event; the bisection
        that locates an event uses the sign of even the tiniest eigenvalue.
        """
        if isinstance(F, CholeskyFactor):
            return 0  # a Cholesky factor exists only of a positive definite matrix: counted for free
        if not self.o.stability:
            return -1
        t0 = time.perf_counter()
        try:
            fac = F if isinstance(F, (LDLFactor, RaisedCholeskyFactor)) else None
            I = inertia(K, factor=fac)
            return I.n_below_zero if signed else I.n_negative
        except InertiaError:
            return -1
        finally:
            self.timer.add("stability", t0)

    # -- recording ---------------------------------------------------------------------------
    def record(self, q, r, p, iterations, ds, n_neg):
        mon = self.monitor_values(q, p)
        # the point's own forces in play, which the next step's corrector would compute first anyway
        norm = float(np.linalg.norm(r[self.free]))
        check = equilibrium(self, norm, r, p, norm)
        point = PathPoint(
            **self.location(q, r, p, self.s), step=self.step, branch=self.branch,
            n_negative=int(n_neg), iterations=int(iterations), ds=float(ds), q=q, monitors=mon,
            residual=check.residual, tolerance=check.tolerance,
        )
        for c in TABLE_COLUMNS:
            self.table[c].append(getattr(point, c))
        for k, v in mon.items():
            self.table[k].append(v)
        if self.o.store_states:
            self.states.append(q.copy())
            self.state_steps.append(self.step)
            self.state_histories.append(self.history())
        return point

    # -- one step with cut-backs -------------------------------------------------------------
    def attempt(self, ds) -> StepPoint:
        """Predict and correct from the current point; return the new point or raise."""
        du0, dp0 = ds * self.t_du, ds * self.t_dp
        u, p, q, r, its = correct(self, self.u, self.p, du0, dp0, ds)
        du, dp = u - self.u, p - self.p
        cosang = self.dot(du, dp, self.t_du, self.t_dp) / max(self.norm(du, dp), 1e-300)
        if cosang < math.cos(math.radians(self.o.max_angle_deg)):
            raise StepFailure(
                f"converged point turned {math.degrees(math.acos(max(-1.0, min(1.0, cosang)))):.1f} deg away "
                "from the predictor (possible branch jump)"
            )
        t_du, t_dp, n_neg, K = self.analyse_point(u, p, du, dp, q)
        return StepPoint(u, p, q, r, its, du, dp, t_du, t_dp, n_neg)

    def take_step(self) -> tuple[float, StepPoint]:
        """One accepted step with its arc length, cut back as often as it takes (or a StepFailure)."""
        o = self.o
        ds = min(self.ds, self.ds_max)
        jump_cuts, jump_seen = 0, None
        last_msg, singular = "", False
        while True:
            try:
                out = self.attempt(ds)
                n_neg = out.n_neg
                jump = n_neg - self.n_neg if (self.n_neg >= 0 and n_neg >= 0) else 0
                if (
                    abs(jump) > 1 and jump != jump_seen
                    and jump_cuts < o.max_inertia_cutbacks and ds > 4 * self.ds_min
                ):
                    # two critical points in one step: a shorter step separates them. The same
                    # jump in the shorter step means a multiple eigenvalue (symmetry): accept it.
                    jump_cuts += 1
                    jump_seen = jump
                    self.rejected += 1
                    ds *= 0.5
                    continue
                return ds, out
            except (StepFailure, SingularMatrixError) as exc:
                last_msg = str(exc)
                singular = isinstance(exc, SingularMatrixError) or exc.singular
                self.rejected += 1
                ds *= 0.5
                self.cut_back = True
                if ds < self.ds_min:
                    # a singular tangent is named by the motions it cannot resist
                    soft = describe_soft_modes(self.system, self.pb.jacobian(self.u, self.p, self.q)[0]) if singular else ""
                    raise StepFailure(
                        f"step {self.step + 1}: arc length cut below ds_min = {self.ds_min:.3e} "
                        f"at parameter {self.p:.6g}; last failure: {last_msg}{'; ' + soft if soft else ''}"
                    ) from None

    # -- main loop --------------------------------------------------------------------------------------
    def run(self, callback, first_point, checkpoint: Checkpoint | None = None, switch_from=None) -> ContinuationResult:
        """Extend the path until a bound, an event stop, the step budget or a failure; the result.

        ``first_point`` is reported to ``callback`` before the first step (None after a resume).
        """
        o = self.o
        status, message, success = "max_steps", "", True
        if self.finished is not None and self.finished[0] not in ("max_steps", "callback"):
            # resumed from the checkpoint of a run that ended for good: nothing to add
            status, message, success = self.finished
            self.timer.t["total"] = time.perf_counter() - self.t_created
            return self.result(success, message, status)
        try:
            if first_point is not None and callback is not None and callback(first_point):
                raise StopIteration
            if switch_from is not None:
                switch_at(self, *switch_from)
                if callback is not None and callback(self.record_current()):
                    raise StopIteration
            while self.step < o.max_steps:
                stop = self.advance(callback)
                if checkpoint is not None and checkpoint.every and self.step % checkpoint.every == 0:
                    save(self, checkpoint)
                if stop is not None:
                    status, message = stop
                    break
            else:
                message = f"reached max_steps = {o.max_steps}"
        except StopIteration:
            status, message = "callback", f"stopped by the callback after step {self.step}"
        except StepFailure as exc:
            status, message, success = "failed", str(exc), False
        self.finished = (status, message, success)
        if checkpoint is not None:
            save(self, checkpoint)
        self.timer.t["total"] = time.perf_counter() - self.t_created
        return self.result(success, message, status)

    def advance(self, callback) -> tuple[str, str] | None:
        """One accepted step with its events, landing and branch switch; why to stop, or None."""
        o = self.o
        lo_b, hi_b = o.parameter_bounds
        self.cut_back = False
        A = (self.u, self.p, self.t_du, self.t_dp)
        n_A = self.n_neg
        ds, B, new_events = self.step_on_branch(A, n_A)
        hit_bound = (B.p >= hi_b and self.p < hi_b) or (B.p <= lo_b and self.p > lo_b) or not lo_b <= B.p <= hi_b
        if hit_bound and o.land_on_bounds:
            landed = land(self, B.u, B.p, lo_b, hi_b)
            if landed is not None:
                B = landed
                ds = self.norm(B.du, B.dp)
                new_events = [e for e in new_events if lo_b <= e.parameter <= hi_b]
        # switching branches: the primary branch ends at the bifurcation point
        switch_ev = None
        if o.on_bifurcation == "switch" and self.switches < o.max_switches:
            bifs = [e for e in new_events if e.kind == "bifurcation" and e.located]
            switch_ev = bifs[0] if bifs else None
        if switch_ev is not None:
            B, ds = self.at_event(switch_ev)
            new_events = [e for e in new_events if e.arc_length <= switch_ev.arc_length]
            hit_bound = False
        t_dp_A = self.t_dp
        self.step += 1
        self.s += ds
        self.u, self.p, self.q = B.u, B.p, B.q
        self.t_du, self.t_dp, self.n_neg = B.t_du, B.t_dp, B.n_neg
        if B.n_neg <= 0:
            self.pb.path_stable()
        self.accept(B.q)
        pt = self.record(B.q, B.r, B.p, B.iterations, ds, B.n_neg)
        self.events.extend(new_events)
        self.adapt_step(ds, B.iterations, t_dp_A)
        if callback is not None and callback(pt):
            raise StopIteration
        # leave the bifurcation point along the critical mode (or the given shape)
        if switch_ev is not None:
            mode = (np.asarray(o.switch_direction, dtype=float)[self.free] if o.switch_direction is not None
                    else switch_ev.mode[self.free])
            switch_at(self, self.u, self.p, self.t_du, self.t_dp, mode, self.s)
            if callback is not None and callback(self.record_current()):
                raise StopIteration
        return self.stop_reason(new_events, hit_bound)

    def step_on_branch(self, A, n_A: int) -> tuple[float, StepPoint, list[PathEvent]]:
        """One accepted step that stays on the branch of A, with the events inside it, located.

        Near a sharp limit point a long step can converge onto another branch
        that crosses the sphere of the arc-length constraint (the complementary
        path of a slightly imperfect structure): its end then differs from A in
        the count of negative eigenvalues without ``dp/ds`` turning, and it
        would be reported as a bifurcation at a load the structure never
        carries. Location finds it out, as a point inside the step that is not
        between its ends or a path it cannot follow from A to the end; the step
        is then taken again, halved. Only a step already at ``ds_min`` may keep
        an event it could not locate (marked so); one that still ends on
        another branch fails the run.
        """
        while True:
            ds, B = self.take_step()
            if not self.o.detect_events:
                return ds, B, []
            must_locate = 0.5 * ds >= self.ds_min
            try:
                return ds, B, self.events_in_step(A, B, ds, n_A, must_locate)
            except LocationFailure as exc:
                if not must_locate:
                    raise StepFailure(
                        f"step {self.step + 1}: every step from parameter {self.p:.6g} down to ds_min = "
                        f"{self.ds_min:.3e} ends on another branch; last: {exc}") from None
                self.rejected += 1
                self.cut_back = True
                self.ds = 0.5 * ds

    def events_in_step(self, A, B: StepPoint, ds: float, n_A: int, must_locate: bool = False) -> list[PathEvent]:
        """The limit and bifurcation points between the last point A and the step's end B, located
        (``must_locate``: or a :class:`LocationFailure`)."""
        new_events = []
        turned = math.copysign(1.0, B.t_dp) != math.copysign(1.0, self.t_dp)
        dn = B.n_neg - n_A if (B.n_neg >= 0 and n_A >= 0) else 0
        if turned:
            ev, _ = locate(self, "limit", A, B, ds, n_A, must_locate)
            ev.n_negative_after = B.n_neg
            new_events.append(ev)
        if (not turned and dn != 0) or (turned and abs(dn) > 1):
            ev, _ = locate(self, "bifurcation", A, B, ds, n_A, must_locate and not turned)
            if turned:
                ev.located = False
                ev.message = "bifurcation and limit point in one step; bracket is the whole step"
            ev.n_negative_after = B.n_neg
            new_events.append(ev)
        return new_events

    def at_event(self, ev: PathEvent) -> tuple[StepPoint, float]:
        """The located bifurcation ``ev`` as the step's end point, with the arc length to it."""
        ev.switched = True
        q = ev.q.copy()
        u, p = q[self.free].copy(), ev.parameter
        r = self.system.residual(q, self.pb.lam_mu(p)[0])
        point = StepPoint(u, p, q, r, 0, u - self.u, p - self.p, ev.tangent[:-1], ev.tangent[-1],
                          ev.n_negative_after)
        return point, ev.arc_length - self.s

    def adapt_step(self, ds: float, iterations: int, t_dp_A: float) -> None:
        """The next step's arc length: from the corrector's iterations, bounded by the approach to a fold."""
        o = self.o
        factor = math.sqrt(o.target_iterations / max(iterations, 1))
        factor = min(max(factor, 0.5), 2.0)
        if self.cut_back:
            factor = min(factor, 1.0)
        self.ds = min(max(ds * factor, self.ds_min), self.ds_max)
        # dp/ds falling towards a fold: the next step may pass it, but not go far beyond
        to_fold = fold_distance(t_dp_A, self.t_dp, ds)
        if to_fold is not None:
            self.ds = min(self.ds, max(FOLD_OVERSHOOT * to_fold, self.ds_min))

    def stop_reason(self, new_events: list[PathEvent], hit_bound: bool) -> tuple[str, str] | None:
        """``(status, message)`` when the run should end after this step, else None."""
        o = self.o
        lo_b, hi_b = o.parameter_bounds
        if new_events and o.on_bifurcation == "stop" and any(e.kind == "bifurcation" for e in new_events):
            return "event", f"stopped at the bifurcation point found in step {self.step}"
        if o.stop_after_events is not None and len(self.events) >= o.stop_after_events:
            return "event", f"stopped after {len(self.events)} events"
        if hit_bound:
            return "parameter_bound", f"parameter reached {self.p:.6g}, bounds [{lo_b:.6g}, {hi_b:.6g}]"
        disp = float(np.max(np.abs(self.q[self.free] - self.system.q_ref[self.free])))
        if o.max_displacement is not None and disp > o.max_displacement:
            return "displacement_bound", (
                f"largest free displacement {disp:.6g} exceeds max_displacement {o.max_displacement:.6g}"
            )
        return None

    # -- effects with history (rod reference frames) ------------------------------------------------
    def accept(self, q):
        """Tell effects with history that ``q`` is accepted (rod frames follow the path), and
        take its member forces as the forces in play of the next step's equilibrium tests."""
        hook = getattr(self.system, "accept", None)
        if hook is not None:
            hook(q)
        self.play = None

    def history(self):
        """A copy of the path history as accepted so far (the rod frames; None without rods)."""
        history = getattr(self.system, "history", None)
        return history() if history is not None else None

    def history_objects(self):
        """Objects holding path history that a checkpoint must carry (rod reference frames)."""
        objects = getattr(self.system, "history_objects", None)
        return objects() if objects is not None else []

    def record_current(self):
        """Record the point a branch switch has just made current."""
        return self.record(*self.last_point)

    def result(self, success, message, status):
        table = {}
        for k, v in self.table.items():
            dtype = int if k in ("step", "branch", "n_negative", "iterations") else float
            table[k] = np.asarray(v, dtype=dtype)
        return ContinuationResult(
            success=success, message=message, status=status, control=self.control, steps=self.step,
            rejected_steps=self.rejected, newton_iterations=self.newton_total, table=table,
            states=self.states, state_steps=self.state_steps, events=self.events, timings=dict(self.timer.t),
            state_histories=self.state_histories,
            monitors=tuple(self.extra_columns()), parameter_scale=math.sqrt(self.c2),
        )
