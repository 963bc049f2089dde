"""Form finding of a hanging net: relaxation plus the reports a designer reads.

:func:`form_find` checks the net (Eqs. 11-12), lets it fall to rest with the
chosen relaxation scheme and reports rope tensions, which ropes ended taut or
slack, the reactions at the suspension points, the equilibrium residual
relative to the weight, and the rise of the shape. Ropes stretched far beyond
what a nearly inextensible rope allows are named in a warning: the shape
there depends on EA, not on the rest lengths alone.
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from dataclasses import fields as dataclass_fields

import numpy as np

from ..errors import ModelError
from ..solvers.relaxation import START_STATES, RelaxationOptions, RelaxationProgress, RelaxationResult, relax
from .hypostatic import HypostaticReport, hypostatic_check
from .net import HangingNet


class HypostaticWarning(UserWarning):
    """The net is not hypostatic (D.o.F <= D.o.C, Eqs. 11-12)."""


class OverstretchWarning(UserWarning):
    """Ropes of the net end stretched beyond the strain limit."""


#: Rope strain above which the hanging shape is reported as depending on EA. MRA
#: ropes are nearly inextensible (strains about 1 / stiffness_ratio = 1e-4 by
#: default), so 1 % is a hundred times what the weight alone should cause.
STRAIN_LIMIT = 0.01

#: Nets with at least this many nodes start from their coarse net by default
#: (``start="auto"``, implicit scheme). Measured on the square nets of
#: ``benchmarks/bench_mra.py`` (``benchmarks/results/bench_mra.md``): at 1,024
#: nodes the coarse net costs what it saves, at 10,000 it saves 23 % of the time, at 99,856 56 %.
COARSE_START_NODES = 5000


@dataclass
class FormFindingResult:
    """A hanging shape and its reports.

    Attributes
    ----------
    net : HangingNet
    relaxation : RelaxationResult
    positions : ndarray, shape (n, 3)
        Node positions at rest.
    tension : ndarray, shape (m,)
        Rope forces [N] (zero for slack ropes), in the order of ``net.rope_edges``.
    length : ndarray, shape (m,)
        Distances between the rope ends at rest [m].
    slack : ndarray of bool, shape (m,)
        Ropes whose ends are closer than their rest length.
    reactions : ndarray, shape (n_supports, 3)
        Forces the suspension points exert on the net [N].
    hypostatic : HypostaticReport
    residual_over_weight : float
        Norm of the out-of-balance force at the free DOFs over the weight.
    rise : float
        Highest suspension point minus the lowest node [m]: the depth of
        the hanging net, the rise of the inverted shell.
    """

    net: HangingNet
    relaxation: RelaxationResult
    positions: np.ndarray
    tension: np.ndarray
    length: np.ndarray
    slack: np.ndarray
    reactions: np.ndarray
    hypostatic: HypostaticReport
    residual_over_weight: float
    rise: float
    warnings: list = field(default_factory=list)
    strain_limit: float = STRAIN_LIMIT
    switched_off: dict = field(default_factory=dict)

    @property
    def converged(self) -> bool:
        return self.relaxation.success

    @property
    def q(self) -> np.ndarray:
        return self.relaxation.q

    @property
    def strain(self) -> np.ndarray:
        """Engineering strain of every rope (negative for slack ropes)."""
        return self.length / self.net.rest_length - 1.0

    @property
    def overstretched(self) -> np.ndarray:
        """Ropes strained beyond ``strain_limit``."""
        return self.strain > self.strain_limit

    def summary(self) -> dict:
        r = self.relaxation
        taut = ~self.slack
        return {
            "converged": bool(r.success),
            "message": r.message,
            "scheme": r.scheme,
            "start": r.start,
            "iterations": int(r.iterations),
            "max_velocity": float(r.max_velocity),
            "max_acceleration": float(r.max_acceleration),
            "velocity_tol": float(r.velocity_tol),
            "acceleration_tol": float(r.acceleration_tol),
            "residual_norm": float(r.residual_norm),
            "residual_over_weight": float(self.residual_over_weight),
            "wall_time_s": float(r.wall_time_s),
            "n_nodes": int(self.net.structure.n_nodes),
            "n_ropes": int(len(self.tension)),
            "n_supports": int(len(self.net.supports)),
            "n_slack_ropes": int(self.slack.sum()),
            "n_taut_ropes": int(taut.sum()),
            "all_ropes_taut": bool(taut.all()),
            "rise": float(self.rise),
            "tension_max": float(self.tension.max()),
            "tension_min_taut": float(self.tension[taut].min()) if taut.any() else 0.0,
            "n_ropes_between_supports": int(len(self.net.info.get("held_ropes", ()))),
            "strain_max": float(self.strain.max()),
            "strain_limit": float(self.strain_limit),
            "n_overstretched_ropes": int(self.overstretched.sum()),
            "total_weight": float(self.net.total_weight()),
            "reaction_sum": self.reactions.sum(axis=0).tolist(),
            "hypostatic": self.hypostatic.as_dict(),
            "warnings": list(self.warnings),
            **({"switched_off": dict(self.switched_off)} if self.switched_off else {}),
        }


def rope_state(net: HangingNet, q: np.ndarray):
    """Tension, length and slackness of every rope at state ``q``."""
    x = q[: 3 * net.structure.n_nodes].reshape(-1, 3)
    e = net.rope_edges
    length = np.linalg.norm(x[e[:, 1]] - x[e[:, 0]], axis=1)
    L = net.rest_length
    slack = length <= L
    tension = np.where(slack, 0.0, net.EA * (length - L) / L)
    return tension, length, slack


def _check_strain_limit(strain_limit) -> None:
    if not (isinstance(strain_limit, (int, float)) and np.isfinite(strain_limit) and strain_limit > 0):
        raise ModelError(f"form finding: strain_limit must be a positive number, got {strain_limit!r}")


def overstretch_message(result: FormFindingResult) -> str | None:
    """A warning counting the result's overstretched ropes and naming the worst; None if there are none."""
    idx = np.flatnonzero(result.overstretched)
    if idx.size == 0:
        return None
    strain = result.strain
    worst = idx[np.argmax(strain[idx])]
    a, b = result.net.rope_edges[worst]
    pa, pb = result.net.structure.nodes[a], result.net.structure.nodes[b]
    return (f"{idx.size} rope(s) stretched beyond {100 * result.strain_limit:g} % at rest, the worst by "
            f"{100 * strain[worst]:.2f} % (rope {worst}, nodes {a}-{b}, planform ({pa[0]:.3g}, {pa[1]:.3g}) to "
            f"({pb[0]:.3g}, {pb[1]:.3g})): the shape there depends on EA, not on the rest lengths alone. "
            "The suspension points may hold the net further apart than its ropes reach (for example an "
            "arched frame on a flat planform), or EA is too low for nearly inextensible ropes")


def evaluate_state(net: HangingNet, system, res: RelaxationResult, report: HypostaticReport, notes=(),
                   strain_limit: float = STRAIN_LIMIT):
    """Reports of a relaxed state.

    The result's ``warnings`` are ``notes`` followed by a message when net
    ropes end strained beyond ``strain_limit``.
    """
    q = res.q
    n = net.structure.n_nodes
    x = q[: 3 * n].reshape(n, 3)
    tension, length, slack = rope_state(net, q)
    R = res.reactions[: 3 * n].reshape(n, 3)[net.supports]
    weight = net.total_weight()
    resid = system.residual(q)[system.free]
    rise = float(x[net.supports, 2].max() - x[:, 2].min())
    out = FormFindingResult(
        net=net, relaxation=res, positions=x, tension=tension, length=length, slack=slack, reactions=R,
        hypostatic=report, residual_over_weight=float(np.linalg.norm(resid) / max(weight, 1e-300)), rise=rise,
        warnings=list(notes), strain_limit=float(strain_limit),
    )
    message = overstretch_message(out)
    if message:
        out.warnings.append(message)
    return out


def coarse_net_progress(progress: Callable[[str], None]):
    """A relaxation callback that reports a coarse net's steps as text (its states are not the net's)."""
    def callback(info) -> None:
        progress(f"  coarse net of {info.q.size // 3:,} nodes: {info.scheme} iteration {info.iteration}: "
                 f"max acceleration {info.max_acceleration:.3e} m/s^2")
    return callback


def coarse_net_outcome(coarse: FormFindingResult, seconds: float) -> str:
    """One line on a hung coarse net: its size, whether it came to rest, its steps and time."""
    r = coarse.relaxation
    return (f"  coarse net of {coarse.net.structure.n_nodes:,} nodes: {'at rest' if r.success else 'not at rest'} "
            f"after {r.iterations} steps, {seconds:.1f} s")


@dataclass(frozen=True)
class FormFindingOptions:
    """Where :func:`form_find` starts and what it reports, beyond the relaxation's own options.

    Attributes
    ----------
    start : {"auto", "reference", "force_density", "coarse_net"}
        Where to start without ``q0``: the planform (``"reference"``, a flat
        start as in the MRA paper), the force-density shape
        (``"force_density"``), or the shape of the net's
        :func:`~shellform.mra.coarsen.coarsened_net`, hung first and
        interpolated (``"coarse_net"``, :func:`~shellform.mra.start.coarse_shape_start`;
        its time is counted in the wall time).
        ``"auto"``: for the implicit scheme the coarse net on nets of
        :data:`COARSE_START_NODES` nodes or more that can be coarsened
        (the coarse net then starts from its own coarse net in turn while it
        is that large), else the force-density shape; the planform for the
        explicit schemes.
    coarsening : int
        Grid lines kept by the ``"coarse_net"`` start (every third by default).
    strain_limit : float
        Net ropes strained beyond this at rest are named in an
        :class:`OverstretchWarning` (default 1 %).
    """

    start: str = "auto"
    coarsening: int = 3
    strain_limit: float = STRAIN_LIMIT


def _split_options(options: RelaxationOptions | None, finding: FormFindingOptions | None,
                   fields: dict) -> tuple[RelaxationOptions, FormFindingOptions]:
    """Both option objects, with the fields given one by one put where they belong."""
    own = {f.name for f in dataclass_fields(FormFindingOptions)}
    finding = replace(finding or FormFindingOptions(), **{k: v for k, v in fields.items() if k in own})
    options = RelaxationOptions() if options is None else options
    rest = {k: v for k, v in fields.items() if k not in own}
    if rest:
        options = replace(options, **rest)
    return options, finding


def _coarse_start(net: HangingNet, system, options: RelaxationOptions, finding: FormFindingOptions,
                  by_default: bool, progress: Callable[[str], None] | None, notes: list):
    """The start shape from the net's coarse net: ``(q0, coarse result, seconds)``.

    ``q0`` is None when the coarse net does not reach every node of the net
    (a note says so) or, started by default, when the net cannot be coarsened.
    """
    from .start import coarse_net_start  # start.py builds on this module

    t0 = time.perf_counter()
    q0, coarse = None, None
    shown = {} if progress is None else {"progress": progress, "callback": coarse_net_progress(progress)}
    try:
        q0, coarse = coarse_net_start(net, finding.coarsening, system=system,
                                      options=replace(options, progress_every=None), **shown)
    except ModelError:
        if not by_default:
            raise
        # a net that cannot be coarsened starts as a small one would
    prep = time.perf_counter() - t0
    if coarse is not None and progress is not None:
        progress(coarse_net_outcome(coarse, prep))
    if coarse is not None and q0 is None:
        notes.append("the coarse net does not reach every node of the net; "
                     "started from the force-density shape instead")
    return q0, coarse, prep


def form_find(net: HangingNet, q0: np.ndarray | None = None, *, options: RelaxationOptions | None = None,
              finding: FormFindingOptions | None = None, progress: Callable[[str], None] | None = None,
              callback: Callable[[RelaxationProgress], bool | None] | None = None,
              v0: np.ndarray | None = None, **fields):
    """Let the net fall into its hanging shape.

    Parameters
    ----------
    net : HangingNet
    q0 : ndarray, optional
        Start state (overrides ``finding.start``).
    options : RelaxationOptions, optional
        The relaxation's scheme, tolerances and limits
        (:class:`~shellform.solvers.relaxation.RelaxationOptions`). Its
        ``max_wall_time`` limits the whole form finding, the coarse nets included.
    finding : FormFindingOptions, optional
        Where to start and which ropes to report as overstretched.
    progress : callable, optional
        ``progress(message)`` receives a line per step of the coarse nets'
        relaxations and one when each is at rest (the full net's steps go to
        ``callback``, whose states have the full net's size).
    callback : callable, optional
        The full net's progress callback (:func:`~shellform.solvers.relaxation.relax`).
    v0 : ndarray, optional
        Start velocity of the explicit schemes (with ``q0``, to go on along a trajectory).
    **fields
        Fields of :class:`FormFindingOptions` or
        :class:`~shellform.solvers.relaxation.RelaxationOptions` given one by
        one (``form_find(net, start="coarse_net", rtol=1e-9)``): they override those of
        ``finding`` and ``options``.

    Returns
    -------
    FormFindingResult

    Raises
    ------
    MechanismError
        When the net is a mechanism the solver cannot handle.
    """
    from .coarsen import coarsening_obstacle  # coarsen.py builds on net.py, as this module does

    options, finding = _split_options(options, finding, fields)
    _check_strain_limit(finding.strain_limit)
    report = hypostatic_check(net.structure, rim=None if net.grid.structured else net.grid.boundary)
    notes = []
    if report.warning:
        warnings.warn(report.warning, HypostaticWarning, stacklevel=2)
        notes.append(report.warning)
    start = finding.start
    if start not in START_STATES + ("coarse_net",):
        raise ModelError(f"form finding: unknown start {start!r}; expected one of {START_STATES + ('coarse_net',)}")
    prep, coarse = 0.0, None
    system = net.system()
    obstacle = coarsening_obstacle(net)
    switched_off = {}
    if obstacle is not None:
        switched_off["coarse_net_start"] = (f"{obstacle}; a net of {COARSE_START_NODES:,} nodes or more starts "
                                            "from the force-density shape instead")
    by_default = (start == "auto" and options.scheme == "implicit" and net.structure.n_nodes >= COARSE_START_NODES
                  and obstacle is None)
    if q0 is None and (start == "coarse_net" or by_default):
        q0, coarse, prep = _coarse_start(net, system, options, finding, by_default, progress, notes)
    if start == "coarse_net":
        start = "auto"
    # the coarse nets' time counts in the wall time and against its limit, even when their start
    # could not be used
    res = relax(system, q0, options=options, start=start, v0=v0, spent_s=prep, callback=callback)
    if coarse is not None and q0 is not None:
        res = replace(res, start="coarse_net")
    out = evaluate_state(net, system, res, report, notes, strain_limit=finding.strain_limit)
    out.switched_off = switched_off
    for w in out.warnings[len(notes):]:
        warnings.warn(w, OverstretchWarning, stacklevel=2)
    return out
