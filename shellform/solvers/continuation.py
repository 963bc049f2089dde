"""Arc-length continuation of equilibrium paths with stability and event detection.

The path is the solution set of ``G(u, p) = 0``, with ``u`` the free DOFs and
``p`` one scalar parameter:

* ``control="load"``: ``p`` is the load factor ``lam`` multiplying
  ``System.load_vector()``; ``G = System.residual(q, lam)[free]`` and
  ``dG/dp = -f_ref[free]``.
* ``control="displacement"``: ``p`` is the magnitude ``mu`` of the prescribed
  displacements (constrained DOFs at ``q_ref + mu * System.direction``);
  ``dG/dp = (K @ direction)[free]`` with ``K = System.tangent(q)``. The
  generalised reaction conjugate to ``mu`` is ``direction . r(q)``.

Each step predicts along the path tangent ``t = (du/dp, 1)``, oriented so
that it keeps the direction of travel (positive inner product with the last
increment), then corrects with Newton's method on ``G`` plus the arc-length
constraint

    |du|^2 + c^2 dp^2 = ds^2          (spherical; ``c = 0``: cylindrical),

where ``c = psi * |dG/dp| / k`` (``k`` the larger of the mean diagonals of the
tangent at the starting and at the reference state) is the displacement per
unit parameter of a typical stiffness, so both parts of the metric have the
same weight for ``psi = 1``. The constraint is solved for the parameter correction
as a quadratic (Crisfield), picking the root closest to the current increment;
where the tangent cannot be factorised (exactly at a limit point) the bordered
system with the linearised constraint is solved instead.

After each accepted step the inertia of the free tangent (number of negative
eigenvalues, :mod:`shellform.solvers.stability`) is compared with the last
point. A sign change of ``dp/ds`` is a *limit point*; a change of the count
while ``p`` keeps its direction is a *bifurcation point*. Both are located by
bisection on the arc length within the step and reported with the state, the
generalised load and the critical mode. At a bifurcation the tracer can
switch to the secondary branch by predicting along the critical mode.
"""

from __future__ import annotations

import json
import math
import os
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..errors import MechanismError, ModelError
from .linear import LDLFactor, LUFactor, SingularMatrixError
from .mechanism import describe_soft_modes
from .equilibrium import ROUNDOFF_RTOL, EquilibriumCheck, forces_in_play, roundoff_level
from .newton import solve_static
from .stability import InertiaError, critical_modes, inertia
from .step_bounds import FOLD_OVERSHOOT, fold_distance, linearised_critical_increment

CONTROLS = ("load", "displacement")
CONSTRAINTS = ("spherical", "cylindrical")
TABLE_COLUMNS = (
    "step", "branch", "arc_length", "lam", "mu", "parameter", "load", "displacement",
    "n_negative", "iterations", "ds",
)
_CHECKPOINT_VERSION = 1


# ---------------------------------------------------------------------------
# result objects
# ---------------------------------------------------------------------------
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
    """One converged point of the path (what a progress callback receives)."""

    step: int
    branch: int
    n_negative: int
    iterations: int
    ds: float
    q: np.ndarray
    monitors: dict[str, float] = field(default_factory=dict)


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
            "max_negative_eigenvalues": int(np.max(t["n_negative"])),
            "events": [e.to_dict() for e in self.events],
            "timings_s": {k: float(v) for k, v in self.timings.items()},
        }


class _StepFailure(Exception):
    """A corrector did not converge (internal; triggers a cut-back).

    ``singular``: the failure came from a tangent that could not be solved with.
    """

    def __init__(self, message: str, singular: bool = False):
        super().__init__(message)
        self.singular = singular


# ---------------------------------------------------------------------------
# the parametrised equilibrium problem
# ---------------------------------------------------------------------------
class _Timer:
    def __init__(self):
        self.t = {"assembly": 0.0, "linear_algebra": 0.0, "stability": 0.0, "event_location": 0.0, "step_bounds": 0.0}

    def add(self, key, t0):
        self.t[key] += time.perf_counter() - t0


class _Problem:
    """``G(u, p)`` and its derivatives for one control mode."""

    def __init__(self, system, control, fixed_lam, fixed_mu, timer, linear_solver):
        self.system = system
        self.control = control
        self.fixed_lam = float(fixed_lam)
        self.fixed_mu = float(fixed_mu)
        self.timer = timer
        self.linear_solver = linear_solver
        self.free = system.free
        self.n_free = system.n_free
        self.f_ref = system.load_vector()
        self.f_dead = system.external_force(0.0)
        self._ldl_prev = None
        self._block = None
        if control == "load":
            if not np.any(self.f_ref != 0.0):
                raise ModelError(
                    "load control: the system has no scaled load (add loads with Structure.add_load(..., scaled=True))"
                )
            self.g_const = -self.f_ref[self.free]
        else:
            d = system.direction
            if system.prescribed.size == 0 or not np.any(d[system.prescribed] != 0.0):
                raise ModelError(
                    "displacement control: no prescribed displacement (use Structure.prescribe with a nonzero direction)"
                )
            self.direction = d

    def lam_mu(self, p):
        return (float(p), self.fixed_mu) if self.control == "load" else (self.fixed_lam, float(p))

    def state(self, u, p):
        _, mu = self.lam_mu(p)
        return self.system.state(u, mu)

    def residual(self, u, p):
        """Free residual, full residual and state."""
        t0 = time.perf_counter()
        q = self.state(u, p)
        lam, _ = self.lam_mu(p)
        r = self.system.residual(q, lam)
        self.timer.add("assembly", t0)
        return r[self.free], r, q

    def _free_block_map(self, K, Kff):
        """Positions in the full CSR data of the entries of the free block."""
        n = K.shape[0]
        full_rows = np.repeat(np.arange(n, dtype=np.int64), np.diff(K.indptr))
        full_key = full_rows * n + K.indices
        order = np.argsort(full_key, kind="stable")
        ff_rows = np.repeat(np.arange(Kff.shape[0], dtype=np.int64), np.diff(Kff.indptr))
        key = self.free[ff_rows] * n + self.free[Kff.indices]
        pos = np.searchsorted(full_key[order], key)
        if np.any(pos >= full_key.size) or np.any(full_key[order][np.minimum(pos, full_key.size - 1)] != key):
            raise RuntimeError("free tangent block not found in the full tangent pattern")
        return order[pos]

    def jacobian(self, u, p, q=None):
        """Free tangent ``K_ff`` and ``dG/dp``."""
        t0 = time.perf_counter()
        if q is None:
            q = self.state(u, p)
        if self.control == "load":
            K = self.system.tangent_free(q)
            g = self.g_const
        else:
            Kfull = self.system.tangent(q)
            if self._block is None or self._block[0] != Kfull.nnz:
                Kff0 = self.system.tangent_free(q)
                self._block = (Kfull.nnz, self._free_block_map(Kfull, Kff0), Kff0.indices, Kff0.indptr)
            _, pos, ind, ptr = self._block
            K = sp.csr_matrix((Kfull.data[pos], ind, ptr), shape=(self.n_free, self.n_free))
            g = (Kfull @ self.direction)[self.free]
        self.timer.add("assembly", t0)
        return K, g

    def factor(self, K):
        """Factorise ``K`` for solves; None when it is singular."""
        t0 = time.perf_counter()
        try:
            if self.linear_solver == "ldl":
                try:
                    F = LDLFactor(K, previous=self._ldl_prev)
                    self._ldl_prev = F
                    return F
                except SingularMatrixError:
                    self._ldl_prev = None
            try:
                return LUFactor(K)
            except SingularMatrixError:
                return None
        finally:
            self.timer.add("linear_algebra", t0)

    def solve(self, F, b):
        t0 = time.perf_counter()
        try:
            try:
                return F.solve(b)
            except SingularMatrixError:
                # an unpivoted LDL^T of an indefinite matrix may lose accuracy: its
                # solve refines and refuses a poor backward error; then LU decides
                if not isinstance(F, LDLFactor):
                    raise
                return LUFactor(F.A).solve(b)
        finally:
            self.timer.add("linear_algebra", t0)

    def bordered_solve(self, K, g, row_u, row_p, rhs_u, rhs_p, F=None):
        """Solve ``[[K, g], [row_u^T, row_p]] [x; y] = [rhs_u; rhs_p]`` (non-singular at limit points).

        GMRES on the bordered matrix, preconditioned by block elimination with
        a factorisation of ``K`` (of ``K + sigma I`` when ``K`` itself is
        singular): the preconditioned operator is the identity up to a
        low-rank term, so a few iterations suffice and no new sparse
        factorisation of the bordered matrix is needed.
        """
        n = K.shape[0]
        if F is None:
            F = self.factor(K)  # timed by factor itself
        if F is None:
            diag = np.abs(K.diagonal())
            sigma = 1e-10 * float(diag.max(initial=1.0))
            F = self.factor(sp.csr_matrix(K + sigma * sp.identity(n, format="csr")))
        t0 = time.perf_counter()
        try:
            rhs = np.concatenate([rhs_u, [rhs_p]])
            if F is not None:
                try:
                    Ag = F.solve(g)
                    schur = row_p - float(row_u @ Ag)
                    if schur != 0.0 and np.isfinite(schur):

                        def precond(v):
                            Af = F.solve(v[:n])
                            y = (v[n] - float(row_u @ Af)) / schur
                            return np.concatenate([Af - y * Ag, [y]])

                        def matvec(v):
                            return np.concatenate([K @ v[:n] + g * v[n], [float(row_u @ v[:n]) + row_p * v[n]]])

                        M = spla.LinearOperator((n + 1, n + 1), matvec=matvec, dtype=float)
                        P = spla.LinearOperator((n + 1, n + 1), matvec=precond, dtype=float)
                        x0 = precond(rhs)
                        sol, info = spla.gmres(M, rhs, x0=x0, M=P, rtol=1e-12, atol=0.0, restart=20, maxiter=5)
                        res = float(np.max(np.abs(matvec(sol) - rhs)))
                        # normwise backward error of the bordered system
                        norm_m = float(abs(K).sum(axis=1).max()) + float(np.max(np.abs(g))) + float(
                            np.sum(np.abs(row_u)) + abs(row_p))
                        scale = norm_m * float(np.max(np.abs(sol))) + float(np.max(np.abs(rhs)))
                        if np.all(np.isfinite(sol)) and res <= 1e-10 * max(scale, 1e-300):
                            return sol[:n], float(sol[n])
                except SingularMatrixError:
                    pass
            # last resort: a sparse LU of the bordered matrix
            Mb = sp.bmat(
                [[K, sp.csr_matrix(g.reshape(-1, 1))], [sp.csr_matrix(row_u.reshape(1, -1)), sp.csr_matrix([[row_p]])]],
                format="csc",
            )
            sol = LUFactor(Mb).solve(rhs)
            return sol[:n], float(sol[n])
        finally:
            self.timer.add("linear_algebra", t0)

    def load_measure(self, r, p):
        if self.control == "load":
            return float(p)
        return float(self.direction @ r)  # only constrained entries of direction are nonzero

    def external_norm(self, p):
        lam, _ = self.lam_mu(p)
        return float(np.linalg.norm(self.f_dead + lam * self.f_ref))


# ---------------------------------------------------------------------------
# the tracer
# ---------------------------------------------------------------------------
class _Tracer:
    def __init__(self, system, control, options):
        if control not in CONTROLS:
            raise ValueError(f"control must be one of {CONTROLS}, got {control!r}")
        o = options
        if o["constraint"] not in CONSTRAINTS:
            raise ValueError(f"constraint must be one of {CONSTRAINTS}, got {o['constraint']!r}")
        if o["linear_solver"] not in ("ldl", "lu"):
            raise ValueError(f"linear_solver must be 'ldl' or 'lu', got {o['linear_solver']!r}")
        self.system = system
        self.control = control
        self.o = o
        self.timer = _Timer()
        self.t_created = time.perf_counter()
        self.pb = _Problem(system, control, o["fixed_lam"], o["fixed_mu"], self.timer, o["linear_solver"])
        self.free = system.free
        self.monitors = dict(o["monitors"] or {})
        for name, spec in self.monitors.items():
            if not callable(spec):
                i = int(spec)
                if not 0 <= i < system.n_dof:
                    raise ModelError(f"monitor {name!r}: DOF index {i} out of range 0..{system.n_dof - 1}")
        # displacement measure
        if control == "displacement":
            self.disp_dof = None
        else:
            dof = o["displacement_dof"]
            if dof is None:
                dof = int(np.argmax(np.abs(self.pb.f_ref)))
            self.disp_dof = int(dof)
            s = np.sign(self.pb.f_ref[self.disp_dof])
            self.disp_sign = float(s) if s != 0 else 1.0
        self.table = {c: [] for c in TABLE_COLUMNS}
        for name in self.monitors:
            if name in self.table:
                raise ModelError(f"monitor name {name!r} clashes with a path table column")
            self.table[name] = []
        self.states: list[np.ndarray] = []
        self.state_steps: list[int] = []
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

    def monitor_values(self, q, p):
        lam, mu = self.pb.lam_mu(p)
        out = {}
        for name, spec in self.monitors.items():
            if callable(spec):
                out[name] = float(spec(q, lam, mu))
            else:
                i = int(spec)
                out[name] = float(q[i] - self.system.q_ref[i])
        return out

    # -- linearisation at a converged point ------------------------------------------------
    def analyse_point(self, u, p, ref_du, ref_dp, q=None):
        """Tangent (oriented along ``ref``) and inertia at a converged point."""
        K, g = self.pb.jacobian(u, p, q)
        F = self.pb.factor(K)
        t_du, t_dp = self.tangent_from(K, g, F, ref_du, ref_dp)
        n_neg = self.count(K, F)
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

        Along the path a tiny eigenvalue counts as zero so that rounding noise
        next to a critical point is not reported as an event; the bisection
        that locates an event uses the sign of even the tiniest eigenvalue.
        """
        if not self.o["stability"]:
            return -1
        t0 = time.perf_counter()
        try:
            fac = F if isinstance(F, LDLFactor) else None
            I = inertia(K, factor=fac)
            return I.n_below_zero if signed else I.n_negative
        except InertiaError:
            return -1
        finally:
            self.timer.add("stability", t0)

    # -- corrector -------------------------------------------------------------------------
    def correct(self, u0, p0, du, dp, ds):
        """Newton on ``G = 0`` plus the arc-length constraint from the predictor ``(du, dp)``."""
        o = self.o
        max_iter = o["max_iterations"]
        complex_roots = 0
        norm0 = previous = None
        for it in range(max_iter + 1):
            u, p = u0 + du, p0 + dp
            R, r, q = self.pb.residual(u, p)
            nR = float(np.linalg.norm(R))
            if not np.isfinite(nR):
                raise _StepFailure(f"non-finite residual at corrector iteration {it}")
            eq = self.equilibrium(nR, r, p, nR if norm0 is None else norm0)
            if eq.converged:
                return u, p, q, r, it
            # stalled near the rounding level: no iteration can do better
            if eq.near_roundoff and (it == max_iter or (previous is not None and nR > 0.1 * previous)):
                if eq.acceptable_at_roundoff:
                    return u, p, q, r, it
                raise _StepFailure(eq.roundoff_failure())
            previous = nR
            if norm0 is None:
                norm0 = max(nR, 1e-300)
            elif nR > 1e8 * norm0:
                raise _StepFailure(f"corrector diverged (|G| grew from {norm0:.3e} to {nR:.3e})")
            if it == max_iter:
                break
            self.newton_total += 1
            K, g = self.pb.jacobian(u, p, q)
            F = self.pb.factor(K)
            a = b = None
            if F is not None:
                try:
                    a = self.pb.solve(F, -R)
                    b = self.pb.solve(F, -g)
                except SingularMatrixError:
                    a = b = None
            if a is not None and float(np.linalg.norm(b)) * self.kbar > 1e6 * max(float(np.linalg.norm(g)), 1e-300):
                # nearly singular tangent (at a critical point): the two solves are huge and
                # their combination cancels, so use the bordered system instead
                a = b = None
            if a is not None:
                w = du + a
                A = float(b @ b) + self.c2
                B = 2.0 * (float(w @ b) + self.c2 * dp)
                C = float(w @ w) + self.c2 * dp * dp - ds * ds
                disc = B * B - 4.0 * A * C
                if disc >= 0.0 and A > 0.0:
                    sq = math.sqrt(disc)
                    # numerically stable pair of roots
                    qq = -0.5 * (B + math.copysign(sq, B))
                    roots = [qq / A, C / qq] if qq != 0.0 else [0.0, 0.0]
                    best = None
                    for rt in roots:
                        du_n, dp_n = w + rt * b, dp + rt
                        score = self.dot(du_n, dp_n, du, dp)
                        if best is None or score > best[0]:
                            best = (score, du_n, dp_n)
                    du, dp = best[1], best[2]
                else:
                    # no real root: step to the point of the line nearest the sphere
                    complex_roots += 1
                    if complex_roots > 3:
                        raise _StepFailure("arc-length constraint has no real root (step too long for the curvature)")
                    rt = -B / (2.0 * A) if A > 0 else 0.0
                    du, dp = w + rt * b, dp + rt
            else:
                # singular tangent: bordered Newton step with the linearised constraint
                cval = self.dot(du, dp, du, dp) - ds * ds
                try:
                    x, y = self.pb.bordered_solve(K, g, 2.0 * du, 2.0 * self.c2 * dp, -R, -cval, F)
                except SingularMatrixError as exc:
                    raise _StepFailure(f"singular bordered system: {exc}", singular=True) from None
                du, dp = du + x, dp + y
            if not (np.all(np.isfinite(du)) and np.isfinite(dp)):
                raise _StepFailure(f"non-finite correction at iteration {it + 1}")
        raise _StepFailure(f"corrector did not converge in {max_iter} iterations ({eq.describe()})")

    def equilibrium(self, norm: float, r: np.ndarray, p: float, unloaded_scale: float) -> EquilibriumCheck:
        """The equilibrium test of a corrector iterate (residual norm ``norm``, full residual ``r``).

        The forces in play are those of the last accepted point, the applied
        loads and the reactions at this iterate; where all are zero (nothing
        loaded yet, displacement control at ``mu = 0``) the residual is judged
        against ``unloaded_scale``, the predictor's imbalance.
        """
        o = self.o
        if self.play is None:
            self.play = forces_in_play(self.system, self.q, self.pb.lam_mu(self.p)[0])
        ext = self.pb.f_dead + self.pb.lam_mu(p)[0] * self.pb.f_ref
        reactions = r[self.system.constrained]
        applied = float(np.linalg.norm(ext))
        scale = max(applied, float(np.linalg.norm(reactions)), self.play[0])
        scale_max = max(float(np.max(np.abs(ext), initial=0.0)), float(np.max(np.abs(reactions), initial=0.0)),
                        self.play[1])
        if scale == 0.0:
            scale = scale_max = unloaded_scale
        return EquilibriumCheck(norm, scale, o["rtol"] * scale + o["atol"], self.round_floor, o["roundoff_rtol"],
                                applied, float(np.max(np.abs(r[self.free]), initial=0.0)), scale_max)

    # -- recording ---------------------------------------------------------------------------
    def record(self, q, r, p, iterations, ds, n_neg):
        mon = self.monitor_values(q, p)
        point = PathPoint(
            **self.location(q, r, p, self.s), step=self.step, branch=self.branch,
            n_negative=int(n_neg), iterations=int(iterations), ds=float(ds), q=q, monitors=mon,
        )
        for c in TABLE_COLUMNS:
            self.table[c].append(getattr(point, c))
        for k, v in mon.items():
            self.table[k].append(v)
        if self.o["store_states"]:
            self.states.append(q.copy())
            self.state_steps.append(self.step)
        return point

    # -- start -----------------------------------------------------------------------------
    def start(self, q0, p0, direction):
        o = self.o
        lam, mu = self.pb.lam_mu(p0)
        st = solve_static(self.system, q0, lam=lam, mu=mu, rtol=o["rtol"], roundoff_rtol=o["roundoff_rtol"], max_iter=50)
        q = st.q
        u = q[self.free].copy()
        K, g = self.pb.jacobian(u, p0, q)
        diag = np.abs(K.diagonal())
        # residuals cannot be computed more accurately than the rounding of the
        # member forces: stiffness times the rounding of the coordinates
        self.round_floor = roundoff_level(diag, q)
        if not st.success:
            raise ModelError(f"no equilibrium at the starting parameter {p0}: {st.message}")
        # stiffness scale for the arc-length metric: the larger of the reference and
        # the starting state, so that a start next to a critical point does not distort it
        d_ref = np.abs(self.pb.jacobian(self.system.q_ref[self.free], p0)[0].diagonal())
        kbar = [float(np.mean(d[d > 0])) for d in (diag, d_ref) if np.any(d > 0)]
        self.kbar = max(kbar) if kbar else 1.0
        F = self.pb.factor(K)
        b = None
        if F is not None:
            try:
                b = self.pb.solve(F, -g)
            except SingularMatrixError:
                b = None
        if b is None:
            soft = describe_soft_modes(self.system, K)
            raise MechanismError(
                f"the tangent is singular at the starting point: {soft}" if soft else
                "the tangent is singular at the starting point; start from a regular state "
                "(or use switch_branch from a located event)"
            )
        nb = float(np.linalg.norm(b))
        if o["constraint"] == "cylindrical":
            if nb == 0.0:
                raise ModelError("cylindrical arc length: the parameter does not move any free DOF")
            c = 0.0
        elif o["parameter_scale"] is not None:
            c = float(o["parameter_scale"])
        else:
            # du/dp of a typical stiffness rather than |K^-1 g|: defined and moderate
            # even when the start is close to a critical point
            ng = float(np.linalg.norm(g))
            c = o["psi"] * (ng / self.kbar if ng > 0 else 1.0)
        self.c2 = c * c
        # no step may be longer than the linearised distance to the nearest critical point
        crit = self.critical_increment(u, p0, K, F, b, direction, q)
        ds_crit = crit * math.sqrt(nb * nb + self.c2) if crit is not None else math.inf
        # first step: parameter increment sets the arc length unless ds is given
        if o["ds"] is not None:
            ds = float(o["ds"])
        else:
            dp0 = o["initial_increment"]
            if dp0 is None:
                lo, hi = o["parameter_bounds"]
                span = hi - p0 if direction >= 0 else p0 - lo
                if span <= 0 or not (np.isfinite(span) or crit is not None):
                    raise ModelError(
                        "continuation needs a step size: give ds, initial_increment or a finite parameter bound"
                    )
                dp0 = min(span / 20.0, crit / 4.0 if crit is not None else math.inf)
            ds = abs(float(dp0)) * math.sqrt(nb * nb + self.c2)
        if not (np.isfinite(ds) and ds > 0):
            raise ModelError(f"initial arc length must be positive and finite, got {ds}")
        self.ds = ds
        self.ds_min = o["ds_min"] if o["ds_min"] is not None else ds * 1e-6
        # an explicit first step is the user's to take; after it no default step exceeds the estimate
        self.ds_max = o["ds_max"] if o["ds_max"] is not None else min(ds * 10.0, max(ds, ds_crit))
        t_du, t_dp = self.tangent_from(K, g, F, None, None)
        if direction < 0:
            t_du, t_dp = -t_du, -t_dp
        self.u, self.p, self.q = u, float(p0), q
        self.t_du, self.t_dp = t_du, t_dp
        self.accept(q)
        self.n_neg = self.count(K, F)
        self.step, self.branch, self.s = 0, 0, 0.0
        r = self.system.residual(q, lam)
        return self.record(q, r, p0, st.iterations, 0.0, self.n_neg)

    def critical_increment(self, u, p, K, F, du_dp, direction, q):
        """Linearised parameter increment to the nearest critical point ahead (None: none or unknown).

        Only from a start whose factorisation ``K = L D L^T`` has a positive
        ``D`` (``K`` positive definite; see
        :func:`~shellform.solvers.step_bounds.linearised_critical_increment`).
        An estimate, not a stability check: a start it cannot judge goes
        without one.
        """
        if not isinstance(F, LDLFactor) or not np.all(F.d > 0.0):
            return None
        t0 = time.perf_counter()
        crit = linearised_critical_increment(lambda uu, pp: self.pb.jacobian(uu, pp), u, p, K, F, du_dp,
                                             1.0 if direction >= 0 else -1.0, float(np.max(np.abs(q))))
        self.timer.add("step_bounds", t0)
        return crit

    # -- one step with cut-backs -------------------------------------------------------------
    def attempt(self, ds):
        """Predict and correct from the current point; return the new point data or raise."""
        du0, dp0 = ds * self.t_du, ds * self.t_dp
        u, p, q, r, its = self.correct(self.u, self.p, du0, dp0, ds)
        du, dp = u - self.u, p - self.p
        cosang = self.dot(du, dp, self.t_du, self.t_dp) / max(self.norm(du, dp), 1e-300)
        if cosang < math.cos(math.radians(self.o["max_angle_deg"])):
            raise _StepFailure(
                f"converged point turned {math.degrees(math.acos(max(-1.0, min(1.0, cosang)))):.1f} deg away "
                "from the predictor (possible branch jump)"
            )
        t_du, t_dp, n_neg, K = self.analyse_point(u, p, du, dp, q)
        return u, p, q, r, its, du, dp, t_du, t_dp, n_neg

    def take_step(self):
        o = self.o
        ds = min(self.ds, self.ds_max)
        jump_cuts, jump_seen = 0, None
        last_msg, singular = "", False
        while True:
            try:
                out = self.attempt(ds)
                n_neg = out[-1]
                jump = n_neg - self.n_neg if (self.n_neg >= 0 and n_neg >= 0) else 0
                if (
                    abs(jump) > 1 and jump != jump_seen
                    and jump_cuts < o["max_inertia_cutbacks"] and ds > 4 * self.ds_min
                ):
                    # two critical points in one step: a shorter step separates them. The same
                    # jump in the shorter step means a multiple eigenvalue (symmetry): accept it.
                    jump_cuts += 1
                    jump_seen = jump
                    self.rejected += 1
                    ds *= 0.5
                    continue
                return ds, out
            except (_StepFailure, SingularMatrixError) as exc:
                last_msg = str(exc)
                singular = isinstance(exc, SingularMatrixError) or exc.singular
                self.rejected += 1
                ds *= 0.5
                self.cut_back = True
                if ds < self.ds_min:
                    # a singular tangent is named by the motions it cannot resist
                    soft = describe_soft_modes(self.system, self.pb.jacobian(self.u, self.p, self.q)[0]) if singular else ""
                    raise _StepFailure(
                        f"step {self.step + 1}: arc length cut below ds_min = {self.ds_min:.3e} "
                        f"at parameter {self.p:.6g}; last failure: {last_msg}{'; ' + soft if soft else ''}"
                    ) from None

    def land(self, u, p, lo_b, hi_b):
        """The point of the last step exactly at the parameter bound it crossed (None if Newton fails)."""
        pb = hi_b if p > hi_b else lo_b
        w = (pb - self.p) / (p - self.p) if p != self.p else 1.0
        if not 0.0 <= w <= 1.0:
            return None
        u = self.u + w * (u - self.u)
        previous = None
        for it in range(self.o["max_iterations"] + 1):
            R, r, q = self.pb.residual(u, pb)
            nR = float(np.linalg.norm(R))
            if not np.isfinite(nR):
                return None
            eq = self.equilibrium(nR, r, pb, nR if previous is None else previous)
            stalled = eq.near_roundoff and previous is not None and nR > 0.1 * previous
            if stalled and not eq.acceptable_at_roundoff:
                return None
            previous = nR
            if eq.converged or stalled:
                du, dp = u - self.u, pb - self.p
                try:
                    t_du, t_dp, n_neg, _ = self.analyse_point(u, pb, du, dp, q)
                except SingularMatrixError:
                    return None
                return u, pb, q, r, it, du, dp, t_du, t_dp, n_neg
            K, _ = self.pb.jacobian(u, pb, q)
            F = self.pb.factor(K)
            if F is None:
                return None
            try:
                u = u + self.pb.solve(F, -R)
            except SingularMatrixError:
                return None
            self.newton_total += 1
        return None

    # -- events ----------------------------------------------------------------------------------
    def solve_between(self, A, lo_pt, hi_pt, lo, hi, sigma):
        """Path point at arc length ``sigma`` from A, between two known path points.

        The predictor interpolates the bracketing points, so the corrector
        stays on this path segment even where another branch crosses nearby;
        a solution that is not between its neighbours is rejected.
        """
        u0, p0 = A[0], A[1]
        w = (sigma - lo) / (hi - lo)
        du = (1 - w) * (lo_pt[0] - u0) + w * (hi_pt[0] - u0)
        dp = (1 - w) * (lo_pt[1] - p0) + w * (hi_pt[1] - p0)
        u, p, q, r, _ = self.correct(u0, p0, du, dp, sigma)
        d_lo = self.norm(u - lo_pt[0], p - lo_pt[1])
        d_hi = self.norm(u - hi_pt[0], p - hi_pt[1])
        if d_lo > 2.0 * (sigma - lo) + 1e-12 * sigma or d_hi > 2.0 * (hi - sigma) + 1e-12 * sigma:
            raise _StepFailure(
                f"bisection point at arc length {sigma:.3e} is not between its neighbours on the path "
                "(another branch crosses this step)"
            )
        return u, p, q, r

    def locate(self, kind, A, B, ds_step, n_A):
        """Bisection on the arc length between point A (sigma = 0) and the step end B."""
        t0 = time.perf_counter()
        u0, p0, tA_du, tA_dp = A
        sign_A = math.copysign(1.0, tA_dp)
        lo, hi = 0.0, ds_step
        lo_pt, hi_pt = (u0, p0, self.pb.state(u0, p0), None), B
        located, last = False, None
        tol = self.o["locate_tol"] * ds_step
        try:
            while hi - lo > tol:
                mid = 0.5 * (lo + hi)
                pt = self.solve_between(A, lo_pt, hi_pt, lo, hi, mid)
                u, p, q, r = pt
                K, g = self.pb.jacobian(u, p, q)
                if kind == "limit":
                    F = self.pb.factor(K)
                    du, dp = self.tangent_from(K, g, F, u - u0, p - p0)
                    before = math.copysign(1.0, dp) == sign_A
                else:
                    before = self.count(K, None, signed=True) == n_A
                if before:
                    lo, lo_pt = mid, pt
                else:
                    hi, hi_pt = mid, pt
            located = True
        except (_StepFailure, SingularMatrixError) as exc:
            last = str(exc)
        # report the bracket end past the event (the step end if bisection failed at once)
        sigma = hi
        u, p, q, r = hi_pt
        if r is None:
            r = self.system.residual(q, self.pb.lam_mu(p)[0])
        p_lo, p_hi = lo_pt[1], hi_pt[1]
        K, g = self.pb.jacobian(u, p, q)
        F = self.pb.factor(K)
        try:
            t_du, t_dp = self.tangent_from(K, g, F, tA_du, tA_dp)
        except SingularMatrixError:
            t_du, t_dp = tA_du, tA_dp
        t1 = time.perf_counter()
        try:
            w, V = critical_modes(K, 1)
            eig, vec = float(w[0]), V[:, 0]
        except InertiaError:
            eig, vec = float("nan"), np.zeros(self.free.size)
        self.timer.add("stability", t1)
        mode = np.zeros(self.system.n_dof)
        mode[self.free] = vec
        reactions = np.zeros(self.system.n_dof)
        reactions[self.system.constrained] = r[self.system.constrained]
        bracket = abs(p_hi - p_lo)
        ev = PathEvent(
            **self.location(q, r, p, self.s + sigma), kind=kind, step=self.step + 1,
            n_negative_before=int(n_A), n_negative_after=-1, located=located, bracket=bracket,
            arc_bracket=hi - lo, eigenvalue=eig, mode=mode, q=q.copy(), reactions=reactions,
            tangent=np.concatenate([t_du, [t_dp]]),
            message="" if located else f"bisection stopped early: {last}",
        )
        self.timer.add("event_location", t0)
        return ev, (u, p, q)

    # -- branch switching -----------------------------------------------------------------------
    def switch(self, u_b, p_b, t_du, t_dp, mode_free, side, ds):
        """Leave a bifurcation point along ``mode_free`` (orthogonalised against the path tangent)."""
        v_du = np.array(mode_free, dtype=float)
        v_dp = 0.0
        proj = self.dot(v_du, v_dp, t_du, t_dp)
        v_du, v_dp = v_du - proj * t_du, v_dp - proj * t_dp
        nv = self.norm(v_du, v_dp)
        if nv == 0.0 or not np.isfinite(nv):
            raise _StepFailure("the branch-switching direction is parallel to the primary path")
        v_du, v_dp = side * v_du / nv, side * v_dp / nv
        last = ""
        for _ in range(6):
            try:
                u, p, q, r, its = self.correct(u_b, p_b, ds * v_du, ds * v_dp, ds)
                du, dp = u - u_b, p - p_b
                along_primary = abs(self.dot(du, dp, t_du, t_dp)) / max(self.norm(du, dp), 1e-300)
                if along_primary < 0.95:
                    return u, p, q, r, its, du, dp
                last = f"corrector returned to the primary branch (cosine {along_primary:.3f} with its tangent)"
            except (_StepFailure, SingularMatrixError) as exc:
                last = str(exc)
            ds *= 0.5
        raise _StepFailure(f"branch switching failed: {last}")

    # -- checkpoints ---------------------------------------------------------------------------------
    def save(self, path):
        meta = {
            "version": _CHECKPOINT_VERSION, "control": self.control, "n_dof": int(self.system.n_dof),
            "n_free": int(self.free.size), "step": int(self.step), "branch": int(self.branch),
            "s": float(self.s), "p": float(self.p), "t_dp": float(self.t_dp), "ds": float(self.ds),
            "ds_min": float(self.ds_min), "ds_max": float(self.ds_max), "c2": float(self.c2),
            "kbar": float(self.kbar), "round_floor": float(self.round_floor), "n_neg": int(self.n_neg), "rejected": int(self.rejected),
            "newton_total": int(self.newton_total), "switches": int(self.switches),
            "events": [e.to_dict() for e in self.events], "monitors": list(self.monitors),
            "finished": self.finished,
        }
        arrays = {f"table_{k}": np.asarray(v, dtype=float) for k, v in self.table.items()}
        n_ev = len(self.events)
        n, nt = self.system.n_dof, self.free.size + 1
        arrays["event_modes"] = np.array([e.mode for e in self.events]).reshape(n_ev, n)
        arrays["event_states"] = np.array([e.q for e in self.events]).reshape(n_ev, n)
        arrays["event_reactions"] = np.array([e.reactions for e in self.events]).reshape(n_ev, n)
        arrays["event_tangents"] = np.array([e.tangent for e in self.events]).reshape(n_ev, nt)
        for k, obj in enumerate(self.history_objects()):
            for name, value in obj.state().items():
                arrays[f"history{k}_{name}"] = np.asarray(value)
        meta["history_objects"] = len(self.history_objects())
        # the states of the points so far: a resumed run then has all of them, as an uninterrupted one
        arrays["states"] = np.array(self.states, dtype=float).reshape(len(self.states), n)
        arrays["state_steps"] = np.asarray(self.state_steps, dtype=np.int64)
        from ..io.checkpoint import fingerprint_record, model_fingerprint, save_checkpoint

        # what the path depends on, so that a resume of another model or other settings is
        # refused: every option but the step budget and what is kept in memory
        settings = {k: v for k, v in self.o.items() if k not in ("max_steps", "store_states", "monitors")}
        settings.update(control=self.control, monitors=sorted(self.monitors))
        meta["fingerprint"] = json.loads(fingerprint_record(model_fingerprint(self.system), settings))
        save_checkpoint(path, meta=np.array(json.dumps(meta)), q=self.q, t_du=self.t_du, **arrays)

    def load(self, path):
        from ..io.checkpoint import CheckpointMismatch, open_checkpoint

        with open_checkpoint(path) as z:
            meta = json.loads(str(z["meta"]))
            if meta.get("version") != _CHECKPOINT_VERSION:
                raise CheckpointMismatch(f"checkpoint {path}: unsupported version {meta.get('version')}")
            if meta["control"] != self.control or meta["n_dof"] != self.system.n_dof or meta["n_free"] != self.free.size:
                raise CheckpointMismatch(
                    f"checkpoint {path} belongs to a different problem (control {meta['control']}, "
                    f"{meta['n_dof']} DOFs, {meta['n_free']} free; this run: control {self.control}, "
                    f"{self.system.n_dof} DOFs, {self.free.size} free)"
                )
            if meta["monitors"] != list(self.monitors):
                raise CheckpointMismatch(f"checkpoint {path}: monitors {meta['monitors']} differ from {list(self.monitors)}")
            from ..io.checkpoint import check_fingerprint, model_fingerprint

            settings = {k: v for k, v in self.o.items() if k not in ("max_steps", "store_states", "monitors")}
            settings.update(control=self.control, monitors=sorted(self.monitors))
            check_fingerprint(path, meta.get("fingerprint"), model_fingerprint(self.system), settings)
            for k in self.table:
                col = z[f"table_{k}"]
                self.table[k] = [int(x) for x in col] if k in ("step", "branch", "n_negative", "iterations") else list(col)
            self.q = z["q"].copy()
            self.t_du = z["t_du"].copy()
            if "states" in z.files:
                self.states = list(z["states"])
                self.state_steps = [int(k) for k in z["state_steps"]]
            modes, states, reacts, tans = z["event_modes"], z["event_states"], z["event_reactions"], z["event_tangents"]
            objs = self.history_objects()
            if meta.get("history_objects", 0) != len(objs):
                raise CheckpointMismatch(
                    f"checkpoint {path} holds history for {meta.get('history_objects', 0)} objects, "
                    f"this system has {len(objs)}"
                )
            for k, obj in enumerate(objs):
                prefix = f"history{k}_"
                obj.restore({key[len(prefix):]: z[key].copy() for key in z.files if key.startswith(prefix)})
        for k in ("step", "branch", "s", "p", "t_dp", "ds", "ds_min", "ds_max", "c2", "kbar", "round_floor", "n_neg", "rejected",
                  "newton_total", "switches"):
            setattr(self, k, meta[k])
        self.u = self.q[self.free].copy()
        self.finished = tuple(meta["finished"]) if meta.get("finished") else None
        self.events = [
            PathEvent(**ev, mode=modes[i], q=states[i], reactions=reacts[i], tangent=tans[i])
            for i, ev in enumerate(meta["events"])
        ]

    # -- main loop --------------------------------------------------------------------------------------
    def run(self, callback, checkpoint, checkpoint_every, first_point, switch_from=None):
        o = self.o
        status, message, success = "max_steps", "", True
        lo_b, hi_b = o["parameter_bounds"]
        if self.finished is not None and self.finished[0] not in ("max_steps", "callback"):
            # resumed from the checkpoint of a run that ended for good: nothing to add
            status, message, success = self.finished
            self.timer.t["total"] = time.perf_counter() - self.t_created
            return self.result(success, message, status)
        try:
            if first_point is not None and callback is not None:
                if callback(first_point):
                    raise StopIteration
            if switch_from is not None:
                self._do_switch(*switch_from)
                pt = self._record_current()
                if callback is not None and callback(pt):
                    raise StopIteration
            while self.step < o["max_steps"]:
                self.cut_back = False
                A = (self.u, self.p, self.t_du, self.t_dp)
                n_A = self.n_neg
                ds, out = self.take_step()
                u, p, q, r, its, du, dp, t_du, t_dp, n_neg = out
                B = (u, p, q, r)
                # events between A and the new point
                new_events = []
                if o["detect_events"]:
                    turned = math.copysign(1.0, t_dp) != math.copysign(1.0, self.t_dp)
                    dn = n_neg - n_A if (n_neg >= 0 and n_A >= 0) else 0
                    if turned:
                        ev, _ = self.locate("limit", A, B, ds, n_A)
                        ev.n_negative_after = n_neg
                        new_events.append(ev)
                    if (not turned and dn != 0) or (turned and abs(dn) > 1):
                        ev, _ = self.locate("bifurcation", A, B, ds, n_A)
                        if turned:
                            ev.located = False
                            ev.message = "bifurcation and limit point in one step; bracket is the whole step"
                        ev.n_negative_after = n_neg
                        new_events.append(ev)
                hit_bound = (p >= hi_b and self.p < hi_b) or (p <= lo_b and self.p > lo_b) or not lo_b <= p <= hi_b
                if hit_bound and o["land_on_bounds"]:
                    landed = self.land(u, p, lo_b, hi_b)
                    if landed is not None:
                        u, p, q, r, its, du, dp, t_du, t_dp, n_neg = landed
                        ds = self.norm(du, dp)
                        new_events = [e for e in new_events if lo_b <= e.parameter <= hi_b]
                # switching branches: the primary branch ends at the bifurcation point
                switch_ev = None
                if o["on_bifurcation"] == "switch" and self.switches < o["max_switches"]:
                    bifs = [e for e in new_events if e.kind == "bifurcation" and e.located]
                    switch_ev = bifs[0] if bifs else None
                if switch_ev is not None:
                    ev = switch_ev
                    ev.switched = True
                    q = ev.q.copy()
                    u, p = q[self.free].copy(), ev.parameter
                    r = self.system.residual(q, self.pb.lam_mu(p)[0])
                    its, ds = 0, ev.arc_length - self.s
                    t_du, t_dp, n_neg = ev.tangent[:-1], ev.tangent[-1], ev.n_negative_after
                    new_events = [e for e in new_events if e.arc_length <= ev.arc_length]
                    hit_bound = False
                # accept the step
                self.step += 1
                self.s += ds
                self.u, self.p, self.q = u, p, q
                self.t_du, self.t_dp, self.n_neg = t_du, t_dp, n_neg
                self.accept(q)
                pt = self.record(q, r, p, its, ds, n_neg)
                self.events.extend(new_events)
                # adapt the step length from the Newton iteration count
                factor = math.sqrt(o["target_iterations"] / max(its, 1))
                factor = min(max(factor, 0.5), 2.0)
                if self.cut_back:
                    factor = min(factor, 1.0)
                self.ds = min(max(ds * factor, self.ds_min), self.ds_max)
                # dp/ds falling towards a fold: the next step may pass it, but not go far beyond
                to_fold = fold_distance(A[3], t_dp, ds)
                if to_fold is not None:
                    self.ds = min(self.ds, max(FOLD_OVERSHOOT * to_fold, self.ds_min))
                if callback is not None and callback(pt):
                    raise StopIteration
                # leave the bifurcation point along the critical mode (or the given shape)
                if switch_ev is not None:
                    direction = o["switch_direction"]
                    mode = (np.asarray(direction, dtype=float)[self.free] if direction is not None
                            else switch_ev.mode[self.free])
                    self._do_switch(self.u, self.p, self.t_du, self.t_dp, mode, self.s)
                    pt = self._record_current()
                    if callback is not None and callback(pt):
                        raise StopIteration
                if checkpoint is not None and checkpoint_every and self.step % checkpoint_every == 0:
                    self.save(checkpoint)
                # bounds
                if new_events and o["on_bifurcation"] == "stop" and any(e.kind == "bifurcation" for e in new_events):
                    status, message = "event", f"stopped at the bifurcation point found in step {self.step}"
                    break
                if o["stop_after_events"] is not None and len(self.events) >= o["stop_after_events"]:
                    status, message = "event", f"stopped after {len(self.events)} events"
                    break
                if hit_bound:
                    status, message = "parameter_bound", f"parameter reached {self.p:.6g}, bounds [{lo_b:.6g}, {hi_b:.6g}]"
                    break
                disp = float(np.max(np.abs(self.q[self.free] - self.system.q_ref[self.free])))
                if o["max_displacement"] is not None and disp > o["max_displacement"]:
                    status, message = "displacement_bound", (
                        f"largest free displacement {disp:.6g} exceeds max_displacement {o['max_displacement']:.6g}"
                    )
                    break
            else:
                message = f"reached max_steps = {o['max_steps']}"
        except StopIteration:
            status, message = "callback", f"stopped by the callback after step {self.step}"
        except _StepFailure as exc:
            status, message, success = "failed", str(exc), False
        self.finished = (status, message, success)
        if checkpoint is not None:
            self.save(checkpoint)
        self.timer.t["total"] = time.perf_counter() - self.t_created
        return self.result(success, message, status)

    def _do_switch(self, u_b, p_b, t_du, t_dp, mode_free, s_b):
        side = 1.0 if self.o["branch_side"] >= 0 else -1.0
        ds = self.o["switch_ds"] if self.o["switch_ds"] is not None else self.ds
        u, p, q, r, its, du, dp = self.switch(u_b, p_b, t_du, t_dp, mode_free, side, ds)
        t_du2, t_dp2, n_neg, _ = self.analyse_point(u, p, du, dp, q)
        self.switches += 1
        self.branch += 1
        self.step += 1
        self.s = s_b + self.norm(du, dp)
        # the secondary branch starts with the step length that left the bifurcation
        self.ds = min(max(self.ds, self.norm(du, dp)), self.ds_max)
        self.u, self.p, self.q = u, p, q
        self.t_du, self.t_dp, self.n_neg = t_du2, t_dp2, n_neg
        self.accept(q)
        self._last = (q, r, p, its, self.norm(du, dp), n_neg)

    # -- effects with history (rod reference frames) ------------------------------------------------
    def accept(self, q):
        """Tell effects with history that ``q`` is accepted (rod frames follow the path), and
        take its member forces as the forces in play of the next step's equilibrium tests."""
        hook = getattr(self.system, "accept", None)
        if hook is not None:
            hook(q)
        self.play = None

    def history_objects(self):
        """Objects holding path history that a checkpoint must carry (rod reference frames)."""
        objs, seen = [], set()
        for e in self.system.effects:
            f = getattr(e, "frames", None)
            if f is not None and hasattr(f, "state") and hasattr(f, "restore") and id(f) not in seen:
                seen.add(id(f))
                objs.append(f)
        return objs

    def _record_current(self):
        return self.record(*self._last)

    def result(self, success, message, status):
        table = {}
        for k, v in self.table.items():
            dtype = int if k in ("step", "branch", "n_negative", "iterations") else float
            table[k] = np.asarray(v, dtype=dtype)
        return ContinuationResult(
            success=success, message=message, status=status, control=self.control, steps=self.step,
            rejected_steps=self.rejected, newton_iterations=self.newton_total, table=table,
            states=self.states, state_steps=self.state_steps, events=self.events, timings=dict(self.timer.t),
            monitors=tuple(self.monitors), parameter_scale=math.sqrt(self.c2),
        )


# ---------------------------------------------------------------------------
# public functions
# ---------------------------------------------------------------------------
def _options(**kw) -> dict:
    o = dict(
        ds=None, initial_increment=None, ds_min=None, ds_max=None, constraint="spherical", psi=1.0,
        parameter_scale=None, max_steps=200, parameter_bounds=(-np.inf, np.inf), max_displacement=None,
        rtol=1e-10, atol=0.0, roundoff_rtol=ROUNDOFF_RTOL, max_iterations=15, target_iterations=4, max_angle_deg=45.0,
        max_inertia_cutbacks=1, stability=True, detect_events=True, locate_tol=1e-8,
        on_bifurcation="continue", branch_side=1, switch_direction=None, switch_ds=None, max_switches=1,
        stop_after_events=None, fixed_lam=1.0, fixed_mu=0.0, monitors=None, displacement_dof=None,
        store_states=True, linear_solver="ldl", land_on_bounds=True,
    )
    unknown = set(kw) - set(o)
    if unknown:
        raise TypeError(f"unknown continuation option(s): {sorted(unknown)}")
    o.update(kw)
    if o["on_bifurcation"] not in ("continue", "switch", "stop"):
        raise ValueError(f"on_bifurcation must be 'continue', 'switch' or 'stop', got {o['on_bifurcation']!r}")
    lo, hi = o["parameter_bounds"]
    o["parameter_bounds"] = (float(lo) if lo is not None else -np.inf, float(hi) if hi is not None else np.inf)
    return o


def trace_path(
    system,
    control: str = "load",
    q0: np.ndarray | None = None,
    p0: float = 0.0,
    direction: int = 1,
    callback: Callable[[PathPoint], bool | None] | None = None,
    checkpoint: str | os.PathLike | None = None,
    checkpoint_every: int = 10,
    resume: bool = False,
    **options,
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
    checkpoint : path, optional
        File (``.npz``) written every ``checkpoint_every`` accepted steps and at
        the end: enough to continue the path.
    resume : bool
        Continue from ``checkpoint`` if that file exists (the options must be the
        same as in the first run). The table and events of the earlier run are
        kept, and so are the states.

    Other Parameters
    ----------------
    ds : float
        First arc length (displacement units). Default: from ``initial_increment``.
    initial_increment : float
        First parameter increment (sets ``ds``). Default: 1/20 of the distance to
        the parameter bound in the direction of travel.
    ds_min, ds_max : float
        Step-length bounds (default ``1e-6 ds`` and ``10 ds``).
    constraint : {"spherical", "cylindrical"}
        Arc-length constraint; cylindrical measures only the free DOFs.
    psi : float
        Weight of the parameter in the spherical constraint (``c = psi |dG/dp| / k``
        with ``k`` the larger of the mean tangent diagonals at the start and at the
        reference state).
    parameter_scale : float
        Override for ``c`` in ``|du|^2 + c^2 dp^2 = ds^2``.
    max_steps : int
        Accepted steps (default 200).
    parameter_bounds : (float, float)
        Stop when the parameter leaves this interval.
    land_on_bounds : bool
        Make the last point lie exactly on the bound it crossed (default True).
    max_displacement : float
        Stop when a free DOF moves further than this from the reference.
    rtol, atol : float
        Corrector tolerance ``|G| <= rtol * scale + atol``; ``scale`` is the
        forces in play (the member forces at the last accepted point, the
        applied loads and the reactions; the predictor's residual while all
        are zero). See :mod:`shellform.solvers.equilibrium`.
    roundoff_rtol : float
        A corrector residual within the rounding level of the member forces
        (``eps |diag K| max|q|`` at the start) is accepted below this fraction
        of the forces in play; one that stalls there above it fails the step,
        which says why.
    max_iterations : int
        Corrector iterations before a cut-back (default 15).
    target_iterations : int
        Step length grows when fewer, shrinks when more iterations were needed.
    max_angle_deg : float
        Reject (and cut back) a step whose converged point lies further than
        this angle from the predictor: a guard against branch jumping.
    max_inertia_cutbacks : int
        Cut-backs allowed when the negative-eigenvalue count jumps by more than
        one in a step (two critical points in one step, or a jump).
    stability : bool
        Count negative eigenvalues at every point (needed for bifurcations).
    detect_events : bool
        Detect and locate limit and bifurcation points.
    locate_tol : float
        Bisection stops when the bracket is this fraction of the step length.
    on_bifurcation : {"continue", "switch", "stop"}
        Stay on the primary branch, follow the secondary branch, or stop.
    branch_side : {1, -1}
        Which half of the secondary branch to follow (sign of the mode).
    switch_direction : ndarray (n_dof,), optional
        Imperfection shape to leave the bifurcation along instead of the
        critical mode.
    switch_ds : float
        Arc length of the switching step (default: the current step length).
    max_switches : int
        Bifurcations at which to switch (default 1).
    stop_after_events : int
        Stop when this many events have been found.
    fixed_lam, fixed_mu : float
        The parameter that is not the path parameter (default: loads in full,
        prescribed DOFs at the reference).
    monitors : dict
        Extra table columns: ``name -> DOF index`` (displacement of that DOF) or
        ``name -> callable(q, lam, mu) -> float``.
    displacement_dof : int
        DOF whose displacement (in the direction of its load) is the
        ``displacement`` column under load control; default the most loaded DOF.
    store_states : bool
        Keep every state in ``result.states`` (default True).
    linear_solver : {"ldl", "lu"}
        ``"ldl"``: qdldl factorisation for the Newton solves and the inertia
        (LU fallback). ``"lu"``: SuperLU solves and a separate LDL for the inertia.

    Returns
    -------
    ContinuationResult
    """
    o = _options(**options)
    tracer = _Tracer(system, control, o)
    first = None
    if resume and checkpoint is not None and os.path.exists(checkpoint):
        tracer.load(checkpoint)
    else:
        q0 = system.q_ref if q0 is None else np.asarray(q0, dtype=float)
        first = tracer.start(q0, p0, direction)
    return tracer.run(callback, checkpoint, checkpoint_every, first)


def switch_branch(
    system,
    event: PathEvent,
    control: str = "load",
    side: int = 1,
    direction: np.ndarray | None = None,
    callback: Callable[[PathPoint], bool | None] | None = None,
    **options,
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
    **options
        As for :func:`trace_path`; ``ds`` (or ``initial_increment``) sets the
        step length and ``switch_ds`` the first step.

    Returns
    -------
    ContinuationResult
        Starting at the bifurcation point (step 0, branch 0) with the secondary
        branch as branch 1.
    """
    o = _options(**options)
    o["branch_side"] = side
    tracer = _Tracer(system, control, o)
    p_b = event.parameter
    first = tracer.start(event.q, p_b, 1)
    # at the bifurcation the tangent is near-singular: reuse the event's tangent
    t = np.asarray(event.tangent, dtype=float)
    tracer.t_du, tracer.t_dp = t[:-1] / tracer.norm(t[:-1], t[-1]), t[-1] / tracer.norm(t[:-1], t[-1])
    mode = np.asarray(direction if direction is not None else event.mode, dtype=float)
    if mode.shape != (system.n_dof,):
        raise ModelError(f"branch switching direction must have {system.n_dof} entries, got shape {mode.shape}")
    return tracer.run(
        callback, None, 0, first,
        switch_from=(tracer.u, tracer.p, tracer.t_du, tracer.t_dp, mode[system.free], 0.0),
    )
