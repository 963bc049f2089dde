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

Stability is counted here from the pivot signs of an LDL^T factorisation
(:func:`count_negative`), and critical modes come from shift-invert Lanczos
about zero (:func:`smallest_eigenpair`): rod tangents in SI units span twelve
orders of magnitude, which the general-purpose tools of
:mod:`shellform.solvers.stability` treat as untrustworthy or shift past.
"""

from __future__ import annotations

import copy
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from ..assembly import System
from ..effects.loads import ConstantForce
from ..errors import ModelError
from ..solvers.continuation import trace_path
from ..solvers.linear import LDLFactor, SingularMatrixError
from ..solvers.newton import solve_static
from ..solvers.stability import InertiaError, critical_modes, inertia, start_vector
from .hemisphere import HemisphereModel, PrestressResult

MODES = ("I", "II")

#: Newton solves use the LDL^T factorisation only: a solve that fails its
#: accuracy check (a tangent next to a critical point) is then retried with a
#: regularising shift, which is cheap, instead of a sparse LU factorisation,
#: which costs twenty LDL^T factorisations on these networks
LINEAR_SOLVER = "ldl"


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
        Configuration before and after (:func:`classify_configuration`).
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
    def max_force(self) -> float:
        """Largest normalised force along the path."""
        return float(np.max(self.y)) if self.y.size else float("nan")

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


def count_negative(K) -> int:
    """Negative eigenvalues of a symmetric tangent, from the pivot signs of its LDL^T factorisation.

    Sylvester's law gives the count exactly for an exact factorisation; the
    count is trusted when a test solve has a small backward error (the
    factorisation was stable), whatever the size of the pivots. A rod network
    in SI units has pivots spanning twelve orders of magnitude (penalty
    joints against the twist of a slender rod), so a test on the pivot size
    alone would reject every factorisation. Otherwise the general
    :func:`~shellform.solvers.stability.inertia` decides.
    """
    try:
        F = LDLFactor(K)
        if F.backward_error() < 1e-11:
            return F.n_negative_pivots
    except SingularMatrixError:
        pass
    try:
        return int(inertia(K).n_below_zero)
    except InertiaError:
        return -1


def _eigsh_about(K, sigma: float):
    """Eigenpair of ``K`` nearest ``sigma`` by shift-invert Lanczos, inverting with LDL^T."""
    import scipy.sparse as sp
    import scipy.sparse.linalg as spla

    n = K.shape[0]
    A = K if sigma == 0.0 else (K - sigma * sp.identity(n, format="csr")).tocsr()
    F = LDLFactor(A)
    op = spla.LinearOperator((n, n), matvec=lambda b: F.solve(np.ravel(b)), dtype=float)
    w, V = spla.eigsh(K, k=1, sigma=sigma, which="LM", OPinv=op, tol=1e-9, v0=start_vector(n))
    return float(w[0]), V[:, 0], F


def smallest_eigenpair(K) -> tuple[float, np.ndarray | None]:
    """The algebraically smallest eigenvalue of a symmetric tangent and its unit eigenvector.

    Lanczos in shift-invert mode, the inverse applied with an LDL^T
    factorisation. When ``K`` is positive definite the shift is zero (the
    smallest eigenvalue is the one closest to zero). Otherwise the shift is
    moved below the whole spectrum, checked by Sylvester's law (no negative
    pivot in ``K - sigma I``), so that the eigenvalue nearest the shift is
    the most negative one rather than a soft positive one. The shift is
    never a fraction of the largest diagonal entry: in a rod network the
    softest eigenvalues are twelve orders of magnitude below it. Falls back
    to :func:`~shellform.solvers.stability.critical_modes` when the
    factorisations fail.
    """
    import scipy.sparse.linalg as spla

    try:
        lam, v, F = _eigsh_about(K, 0.0)
        if F.n_negative_pivots == 0 or (lam < 0 and F.n_negative_pivots == 1):
            return lam, v
        sigma = -2.0 * abs(lam)
        for _ in range(40):
            import scipy.sparse as sp

            G = LDLFactor((K - sigma * sp.identity(K.shape[0], format="csr")).tocsr())
            if G.n_negative_pivots == 0:
                lam, v, _ = _eigsh_about(K, sigma)
                return lam, v
            sigma *= 4.0
    except (SingularMatrixError, RuntimeError, spla.ArpackNoConvergence, ValueError):
        pass
    try:
        w, V = critical_modes(K, 1)
        return float(w[0]), V[:, 0]
    except InertiaError:
        return float("nan"), None


def _lowest_mode(K) -> np.ndarray | None:
    return smallest_eigenpair(K)[1]


def _lowest_eigenvalue(K) -> float:
    return smallest_eigenpair(K)[0]


def _dynamic_step_out(setup: IndentationSetup, q: np.ndarray, mu: float, h: float, damping: float, t_max: float):
    """Let the structure move from ``q`` under damped implicit Euler dynamics until it is nearly at rest.

    This is the paper's own way through a snap (inertia and damping carry the
    structure to the next stable state). Returns the last state, or ``q``
    when no time integrator is available.
    """
    try:
        from ..solvers.implicit_euler import implicit_euler, lumped_mass
    except ImportError:  # pragma: no cover - the integrator is optional here
        return q, 0
    system = setup.system
    mass = lumped_mass(system.structure, setup.model.network)
    scale = max(float(np.linalg.norm(system.residual(system.state(mu=mu, base=q))[system.constrained])), 1e-300)

    def stop(t, qq, v, static):
        return static <= 1e-7 * scale

    res = implicit_euler(system, h, t_max, q0=q, mass=mass, damping=damping, mu=mu, stop=stop,
                         linear_solver=LINEAR_SOLVER)
    return res.q, int(sum(res.newton_iterations))


def _settle(setup: IndentationSetup, q0: np.ndarray, mu: float, mode_free: np.ndarray | None, amplitude: float,
            method: str = "dynamic", max_tries: int = 4, rounds: int = 10, iterations_per_round: int = 40,
            time_step: float = 1.0e-3, damping: float = 100.0, t_max: float = 0.5):
    """A stable equilibrium at ``mu`` reached from the critical state ``q0``.

    The start is pushed along ``mode_free`` (the critical mode) so that it
    leaves the unstable state; then either damped dynamics (``"dynamic"``,
    implicit Euler with time step ``time_step`` and mass-proportional damping
    ``damping`` [1/s], for at most ``t_max`` seconds) or a pure energy descent
    (``"energy"``, Newton with regularised steps) carries it downhill, and
    Newton polishes the result. When it ends on a saddle, it is pushed along
    the saddle's unstable mode and tried again.
    """
    system = setup.system
    free = system.free
    n_x = 3 * setup.model.structure.n_nodes
    q = np.array(q0, dtype=float)
    iterations = 0
    for _ in range(max_tries):
        if mode_free is not None:
            d = np.zeros(system.n_dof)
            d[free] = mode_free
            trans = np.abs(d[:n_x]).max()
            if trans > 0:
                q = q + amplitude * setup.model.radius * d / trans
        if method == "auto":
            # a plain energy descent first; damped dynamics only when it stalls
            frames = setup.model.network.frames.state()
            res = solve_static(system, q, mu=mu, merit="energy", max_iter=30, rtol=1e-9)
            iterations += res.iterations
            if res.success and count_negative(system.tangent_free(res.q)) == 0:
                system.accept(res.q)
                return res.q, iterations, "stable"
            setup.model.network.frames.restore(frames)
            q, its = _dynamic_step_out(setup, q, mu, time_step, damping, t_max)
            iterations += its
        elif method == "dynamic":
            q, its = _dynamic_step_out(setup, q, mu, time_step, damping, t_max)
            iterations += its
        # descend in rounds, accepting the state in between: a snap can turn rod
        # edges far from the stored frames, and the frames must follow
        for _ in range(rounds):
            # LU fallback here: next to a supercritical bifurcation the stable
            # state has a nearly singular tangent and shifted steps crawl
            res = solve_static(system, q, mu=mu, merit="energy", max_iter=iterations_per_round, rtol=1e-9)
            iterations += res.iterations
            q = res.q
            system.accept(q)
            if res.success:
                break
        else:
            return None, iterations, f"energy descent failed: {res.message}"
        K = system.tangent_free(q)
        n_neg = count_negative(K)
        if n_neg == 0:
            return q, iterations, "stable"
        mode_free = _lowest_mode(K)
        if mode_free is None:
            return None, iterations, "could not compute the unstable mode of a saddle"
    return None, iterations, f"still unstable after {max_tries} pushes"


def _locate_stability_loss(setup, qa, mua, qb, mub, tol):
    """Locate where the path between a stable point A and an unstable point B loses stability.

    ``mu`` increases from A to B (no fold in between). Bisection on ``mu``
    with the stability of each point from the inertia of its tangent (the
    eigenvalue that crosses zero need not be the smallest one at A: soft
    twisting modes of the rods can lie below it), each point solved by
    Newton from the interpolated state. Returns ``(mu, q, located)``: the
    middle of the final bracket, the state at its unstable end, and whether
    the bracket came down to ``tol``.
    """
    system = setup.system
    lo, hi = (mua, qa), (mub, qb)
    while hi[0] - lo[0] > tol:
        mu = 0.5 * (lo[0] + hi[0])
        start = 0.5 * (lo[1] + hi[1])
        res = solve_static(system, start, mu=mu, merit="residual", max_iter=30, linear_solver=LINEAR_SOLVER)
        if not res.success:
            # next to the critical point the tangent is nearly singular and the
            # plain Newton step overshoots; a regularised step does not
            res = solve_static(system, start, mu=mu, merit="energy", max_iter=30, linear_solver=LINEAR_SOLVER)
        if not res.success:
            return 0.5 * (lo[0] + hi[0]), hi[1], False
        if count_negative(system.tangent_free(res.q)) == 0:
            lo = (mu, res.q)
        else:
            hi = (mu, res.q)
    return 0.5 * (lo[0] + hi[0]), hi[1], True


def trace_indentation(
    setup: IndentationSetup,
    dD_max: float | None = None,
    increment: float = 0.01,
    snap_offset: float = 2.0e-3,
    push: float = 2.0e-2,
    min_jump: float = 0.03,
    merge_within: float = 0.01,
    locate_tol: float = 5.0e-4,
    max_snaps: int = 12,
    max_steps: int = 3000,
    rtol: float = 1e-9,
    snap_method: str = "dynamic",
    snap_time_step: float = 1.0e-3,
    snap_damping: float = 100.0,
    min_drop: float = 0.05,
    classify: bool = True,
    store_states: bool = False,
    progress: Callable[[float, float, int], None] | None = None,
) -> IndentationResult:
    """Trace the indentation from ``dD = 0`` to ``dD_max`` through every snap.

    Parameters
    ----------
    setup : IndentationSetup
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
    progress : callable, optional
        ``progress(dD / R, force / (EI / R^2), n_negative)`` after every point.
    """
    t0 = time.perf_counter()
    model, system = setup.model, setup.system
    path_states: list[np.ndarray] = []
    R = model.radius
    dD_max = 2.0 * R if dD_max is None else float(dD_max)
    model.network.frames.restore(setup.frames_state)
    xs, fs, seg, negs, labels = [], [], [], [], []
    snaps: list[Snap] = []
    exchanges: list[Snap] = []
    states: dict[float, np.ndarray] = {}
    totals = {"steps": 0, "newton": 0, "rejected": 0}
    timings: dict[str, float] = {"stability": 0.0}
    q, p, segment = np.array(system.q_ref), 0.0, 0
    message, success = "", True

    def add_point(qq, mu, n_neg):
        xs.append(mu)
        fs.append(setup.force(qq))
        seg.append(segment)
        negs.append(n_neg)
        labels.append(classify_configuration(model, qq) if classify else "")
        if store_states:
            path_states.append(np.array(qq))
        if progress is not None:
            progress(mu / R, fs[-1] / setup.force_scale, n_neg)

    losses = 0
    segment_start, snap_start_q = None, None
    while True:
        last = {}

        def on_point(pt):
            # carry the rod frames along the path; stop at the first unstable point
            system.accept(pt.q)
            ts = time.perf_counter()
            n_neg = count_negative(system.tangent_free(pt.q))
            timings["stability"] += time.perf_counter() - ts
            if n_neg != 0:
                last["unstable"] = (pt.mu, pt.q.copy(), n_neg)
                return True
            if not (pt.step == 0 and xs and abs(pt.mu - xs[-1]) < 1e-15 and segment == seg[-1]):
                add_point(pt.q, pt.mu, 0)
            last["stable"] = (pt.mu, pt.q.copy())
            return None

        res = trace_path(
            system, "displacement", q0=q, p0=p, callback=on_point,
            initial_increment=increment * R, parameter_bounds=(-np.inf, dD_max),
            max_steps=max_steps - totals["steps"], rtol=rtol, store_states=False,
            stability=False, locate_tol=1e-2,
        )
        totals["steps"] += res.steps
        totals["newton"] += res.newton_iterations
        totals["rejected"] += res.rejected_steps
        for k, v in res.timings.items():
            timings[k] = timings.get(k, 0.0) + v
        if "stable" in last:
            states[last["stable"][0] / R] = last["stable"][1]
        if res.status == "parameter_bound" or (res.status == "callback" and "unstable" not in last):
            message = f"reached dD/R = {xs[-1] / R if xs else 0:.4g}"
            break
        if res.status != "callback":
            success = False
            message = f"continuation ended at dD/R = {xs[-1] / R if xs else 0:.4g}: {res.message}"
            break
        if "stable" not in last:
            success = False
            message = f"the starting state at dD/R = {p / R:.4g} is unstable"
            break
        losses += 1
        if losses > max_snaps:
            message = f"stopped after {max_snaps} losses of stability at dD/R = {last['stable'][0] / R:.4g}"
            break
        # where the branch ends: a fold of dD located by the tracer, or a bifurcation
        folds = [e for e in res.events if e.kind == "limit" and e.step == res.steps]
        mu_a, q_a = last["stable"]
        mu_b, q_b, _ = last["unstable"]
        if folds and folds[-1].located:
            ev = folds[-1]
            mu_c, q_c, kind, located = ev.mu, ev.q, "limit", True
            mode_free = _lowest_mode(system.tangent_free(q_c))
        elif mu_b > mu_a:
            mu_c, q_c, located = _locate_stability_loss(setup, q_a, mu_a, q_b, mu_b, locate_tol * R)
            kind = "bifurcation"
            mode_free = _lowest_mode(system.tangent_free(q_c))
        else:
            mu_c, q_c, kind, located = mu_a, q_a, "unlocated", False
            mode_free = _lowest_mode(system.tangent_free(q_b))
        f_c = setup.force(q_c)
        # the stable state beyond the critical point; next to a supercritical
        # bifurcation it is itself nearly critical and Newton crawls, so a
        # failure is retried a little further on (with the rod frames of q_c)
        frames = model.network.frames.state()
        for factor in (1.0, 4.0, 16.0):
            model.network.frames.restore(frames)
            mu_new = min(mu_c + factor * snap_offset * R, dD_max)
            q_new, its, why = _settle(setup, q_c, mu_new, mode_free, push, method=snap_method,
                                      time_step=snap_time_step, damping=snap_damping)
            totals["newton"] += its
            if q_new is not None:
                break
        if q_new is None:
            success = False
            message = f"no stable state found beyond the critical point at dD/R = {mu_c / R:.4g}: {why}"
            break
        system.accept(q_new)
        x_c, x_new = model.positions(q_c), model.positions(q_new)
        jump = float(np.abs(x_new - x_c).max() / R)
        before = classify_configuration(model, q_c) if classify else ""
        event = Snap(mu_c, mu_c / R, f_c / setup.force_scale, setup.force(q_new) / setup.force_scale, kind,
                     located, before, "", jump)
        f_new = setup.force(q_new)
        if abs(f_new - f_c) < min_drop * max(abs(f_c), 1e-3 * setup.force_scale):
            jump = min(jump, 0.0)  # no force drop: the path goes on smoothly, not a snap
        if jump >= min_jump and snaps and segment_start is not None and mu_c - segment_start < merge_within * R:
            # the state a snap landed in is lost again right away: in a dynamic
            # experiment this is one snap, so merge it into the previous one
            keep = [i for i, s in enumerate(seg) if s != segment]
            for lst in (xs, fs, seg, negs, labels) + ((path_states,) if store_states else ()):
                lst[:] = [lst[i] for i in keep]
            event = snaps[-1]
            event.force_after = setup.force(q_new) / setup.force_scale
            event.jump = float(np.abs(x_new - model.positions(snap_start_q)).max() / R)
            event.merged += 1
        elif jump >= min_jump:
            segment += 1
            states[mu_c / R] = np.array(q_c)
            snaps.append(event)
            snap_start_q = np.array(q_c)
        else:
            exchanges.append(event)
        add_point(q_new, mu_new, 0)
        event.label_after = labels[-1]
        states[mu_new / R] = q_new.copy()
        segment_start = mu_new if jump >= min_jump else segment_start
        q, p = q_new, mu_new
        if mu_new >= dD_max:
            message = f"reached dD/R = {mu_new / R:.4g}"
            break
    timings["total"] = time.perf_counter() - t0
    return IndentationResult(
        mode=setup.mode, radius=R, force_scale=setup.force_scale, dD=np.asarray(xs), force=np.asarray(fs),
        segment=np.asarray(seg, dtype=int), n_negative=np.asarray(negs, dtype=int), snaps=snaps, labels=labels,
        states=states, success=success, message=message,
        steps=totals["steps"], newton_iterations=totals["newton"], rejected_steps=totals["rejected"],
        n_dof=system.n_dof, n_free=system.n_free, wall_time_s=time.perf_counter() - t0, timings=timings,
        exchanges=exchanges, path_states=path_states,
    )


# ---------------------------------------------------------------------------
# configurations
# ---------------------------------------------------------------------------
def central_profiles(model: HemisphereModel, q: np.ndarray) -> list[np.ndarray]:
    """Side views ``(xi, z)`` of the two central rods (u0 along x, v0 along y)."""
    x = model.positions(q)
    out = []
    for family, axis in (("u", 0), ("v", 1)):
        nodes = model.rod_nodes[model.rod_index(family, 0)]
        out.append(np.stack([x[nodes, axis], x[nodes, 2]], axis=1))
    return out


def _half_bulge(prof: np.ndarray, apex: int, side: int) -> float:
    """Signed largest offset of one half of a side view from its chord (end to apex), up positive."""
    half = prof[: apex + 1] if side < 0 else prof[apex:][::-1]
    end, top = half[0], half[-1]
    chord = top - end
    normal = np.array([-chord[1], chord[0]]) * (-side)  # points up for a horizontal chord
    normal /= max(np.linalg.norm(normal), 1e-300)
    offset = (half - end) @ normal
    return float(offset[np.argmax(np.abs(offset))])


def configuration_features(model: HemisphereModel, q: np.ndarray) -> dict[str, float]:
    """Shape measures of a state (lengths relative to ``R``).

    ``bulges``: signed bulge of the four half central rods (u0 left, u0
    right, v0 left, v0 right) from their chords, up positive;
    ``apex_height``, ``top`` and ``bottom``: heights of the apex and of the
    highest and lowest points of the central rods; ``shear``: mean sideways
    deflection of the central rods, odd along each rod and of opposite sense
    on the two rods (the scissor mode of the net, closing the angle between
    the rods at the apex towards a diagonal); ``twist``: the same with equal
    senses (a rotation of the net about the vertical axis); ``lateral``: the
    largest sideways deflection of a central rod; ``asymmetry``: the largest
    distance of a node from its place in the state mirrored about the x-z
    and the y-z plane (zero for the symmetric states).
    """
    R = model.radius
    x = model.positions(q)
    bulges, tops, bottoms, odd, lateral = [], [], [], [], 0.0
    apex_z = float(x[model.apex_nodes, 2].mean() / R)
    for family, along, across in (("u", 0, 1), ("v", 1, 0)):
        k = model.rod_index(family, 0)
        nodes = model.rod_nodes[k]
        prof = np.stack([x[nodes, along], x[nodes, 2]], axis=1) / R
        apex = int(np.argmin(np.abs(np.asarray(model.rod_stations[k]))))
        bulges += [_half_bulge(prof, apex, -1), _half_bulge(prof, apex, 1)]
        tops.append(prof[:, 1].max())
        bottoms.append(prof[:, 1].min())
        side = x[nodes, across] / R
        odd.append(float(np.mean(np.sign(x[nodes, along]) * side)))
        lateral = max(lateral, float(np.abs(side).max()))
    asym = []
    for axis in (0, 1):
        y = x[model.mirror_map(axis)].copy()
        y[:, axis] *= -1.0
        asym.append(float(np.linalg.norm(x - y, axis=1).max() / R))
    return {
        "bulges": bulges,
        "asymmetry": asym,
        "apex_height": apex_z,
        "top": float(max(tops)),
        "bottom": float(min(bottoms)),
        "shear": 0.5 * (odd[0] + odd[1]),
        "twist": 0.5 * (odd[0] - odd[1]),
        "lateral": lateral,
    }


def classify_configuration(model: HemisphereModel, q: np.ndarray, tol: float = 0.03, apex_tol: float = 0.005) -> str:
    """Name the configuration of the gridshell (the paper's U+, O+, W, S, O-, U-).

    The paper names the shapes only in its figures; this is our reading,
    in terms of :func:`configuration_features` (lengths relative to ``R``):

    * ``S``: one half of a central rod bulges up and the other half of the
      same rod bulges down, by more than ``tol`` (the asymmetric pattern);
    * ``W``: otherwise, when the state has lost its mirror symmetry about the
      vertical planes through the central rods (``asymmetry > tol``): in mode I
      the net shears, the central rods turning towards one diagonal; in
      mode II (apex clamped) the rods wave sideways in a pinwheel. Both come in
      mirror images;
    * otherwise symmetric: ``U+`` when the apex is the highest point of the
      central rods (within ``apex_tol``: a dome), ``O+`` when the halves bulge
      up around a dimpled apex (a ring-shaped crest), ``U-`` when the apex is
      the lowest point (the inverted dome), ``O-`` when the halves bulge down
      around a raised apex (a ring-shaped trough).
    """
    f = configuration_features(model, q)
    b = f["bulges"]
    for left, right in ((b[0], b[1]), (b[2], b[3])):
        if (left > tol and right < -tol) or (left < -tol and right > tol):
            return "S"
    if max(f["asymmetry"]) > tol:
        return "W"
    up = float(np.mean(b)) > 0
    if up:
        return "U+" if f["apex_height"] >= f["top"] - apex_tol else "O+"
    return "U-" if f["apex_height"] <= f["bottom"] + apex_tol else "O-"
