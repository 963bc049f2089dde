"""Arc-length continuation of a scene: the path, its events and files."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from .. import scene as scenes
from ..io import write_json, write_mode, write_series
from ..io.mesh import evaluated_with
from ..io.table import PathPlot, plot_path, write_path_csv
from ..model import AXES
from ..progress import Progress, Status, indented
from .common import build_scene_model, model_sizes, plot_or_note, series_time, write_final_state


def path_fraction(point, options: dict) -> float:
    """How far a path has got: the larger of the steps taken and the parameter's way to its upper bound."""
    from ..solvers.continuation import ContinuationOptions

    max_steps = options.get("max_steps", ContinuationOptions.max_steps)
    fraction = point.step / max_steps
    upper = (options.get("parameter_bounds") or (None, None))[1]
    if upper is not None and np.isfinite(upper) and upper > 0:
        fraction = max(fraction, point.parameter / upper)
    return fraction


@dataclass(frozen=True)
class PathFiles:
    """What :func:`run_continuation_case` writes and keeps.

    Attributes
    ----------
    name : str
        Stem of the file names.
    plot : PathPlot, optional
        The plot's file, abscissa and labels; None draws none.
    checkpoint_every : int
        Steps between checkpoints.
    resume : bool
        Continue from an existing checkpoint.
    """

    name: str = "path"
    plot: PathPlot | None = PathPlot()
    checkpoint_every: int = 10
    resume: bool = True


def run_continuation_case(system, out_dir, control: str = "load", files: PathFiles = PathFiles(), *,
                          progress: Progress | None = None, callback=None, **options):
    """Trace a path and write its files to ``out_dir``.

    Writes ``{name}.csv`` (path table), the force-displacement plot, for
    every critical point ``{name}_critical_{k}.vtu`` (the state there, its
    buckling mode as point data ``mode``), ``{name}_events.json`` (outcome
    and events) and keeps ``{name}_checkpoint.npz``: started again with the
    same arguments, an interrupted run resumes from its last checkpoint.

    Parameters
    ----------
    system : System
    out_dir : path-like
        Created if missing.
    control : {"load", "displacement"}
    files : PathFiles
        File names, plot and checkpointing.
    progress : callable, optional
        Receives a status per converged point and the outcome.
    callback : callable, optional
        Also called with each :class:`~shellform.solvers.continuation.PathPoint`;
        returning True stops the run.
    **options
        Passed to :func:`~shellform.solvers.continuation.trace_path`.

    Returns
    -------
    result : ContinuationResult
    summary : dict
        JSON-ready outcome, events and file names (also written to
        ``{name}_events.json``).
    """
    from ..io.checkpoint import CheckpointFile
    from ..solvers.continuation import trace_path

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    ck = out / f"{files.name}_checkpoint.npz"

    def on_point(pt):
        if progress is not None:
            progress(Status(
                f"step {pt.step:4d}  branch {pt.branch}  parameter {pt.parameter: .6e}  load {pt.load: .6e}  "
                f"displacement {pt.displacement: .6e}  negative eigenvalues {pt.n_negative}  "
                f"iterations {pt.iterations}  residual {pt.residual:.1e} (tolerance {pt.tolerance:.1e})",
                path_fraction(pt, options)))
        return callback(pt) if callback is not None else None

    result = trace_path(system, control, callback=on_point,
                        checkpoint=CheckpointFile(ck, files.checkpoint_every, files.resume), **options)
    summary = write_path_files(result, system, out, files, progress)
    if progress is not None:
        progress(f"{result.message} ({result.steps} steps, {len(result.events)} events)")
    return result, summary


def write_path_files(result, system, out: Path, files: PathFiles, progress: Progress | None = None) -> dict:
    """The table, the critical points' states and modes, the events file and the plot of a traced path.

    Returns the summary written to ``{name}_events.json``, with the file names.
    """
    name = files.name
    written = [write_path_csv(result, out / f"{name}.csv").name]
    summary = result.summary()
    for number, (event, record) in enumerate(zip(result.events, summary["events"]), start=1):
        written.append(write_mode(out / f"{name}_critical_{number}.vtu", system, event.q, event.mode,
                                  event.lam, history=event.history).name)
        record.update(number=number, file=written[-1])
    summary["files"] = written + [f"{name}_events.json", f"{name}_checkpoint.npz"]
    # the outcome is on disk before the plot is drawn
    write_json(out / f"{name}_events.json", summary)
    if files.plot is None:
        return summary
    default_y = "load factor" if result.control == "load" else "reaction conjugate to the prescribed displacement"
    plots, notes = [], []
    png = out / (files.plot.file or f"{name}.png")
    shown = replace(files.plot, ylabel=files.plot.ylabel or default_y)
    plot_or_note(png, lambda: plot_path(result, png, shown), plots, notes)
    summary["files"] = written[:1] + plots + summary["files"][1:]
    if notes:
        summary["warnings"] = notes
        for note in notes:
            if progress is not None:
                progress(note)
    write_json(out / f"{name}_events.json", summary)
    return summary


def write_path_series(path: Path, system, result, load_factor: float) -> str:
    """The stored states of a traced path as an XDMF series; returns what its time is.

    The time is the path parameter while it increases, else the arc length,
    else the step number (:func:`~shellform.analyses.common.series_time`).
    """
    row = {int(step): k for k, step in enumerate(result.table["step"])}
    rows = [row.get(int(step)) for step in result.state_steps]
    column = lambda c: [result.table[c][r] if r is not None else np.nan for r in rows]  # noqa: E731
    lam = [v if np.isfinite(v) else load_factor for v in column("lam")]
    name, times = series_time(("path parameter", column("parameter")), ("arc length", column("arc_length")),
                              ("step", result.state_steps))
    # each state with the rod frames it was found with
    histories = result.state_histories or [None] * len(result.states)
    write_series(path, system, list(zip(times, result.states, lam, histories)), time_name=name)
    return name


def path_options(scene: dict, structure, system) -> tuple[dict, str | None, Callable | None]:
    """The ``trace_path`` options a scene's ``[analysis.continuation]`` asks for.

    Returns
    -------
    options : dict
        Keyword arguments of :func:`~shellform.solvers.continuation.trace_path`.
    monitor : str or None
        The monitor column of ``monitor_node`` (None without one).
    event_x : callable or None
        ``event_x(event)``: the monitor's value at an event (the plot's abscissa).
    """
    a = scene["analysis"]
    c = a["continuation"]
    options = dict(
        max_steps=c["max_steps"], parameter_bounds=(c["parameter_min"], c["parameter_max"]),
        constraint=c["constraint"], stability=c["stability"], on_bifurcation=c["on_bifurcation"],
        branch_side=c["branch_side"], rtol=a["rtol"], fixed_lam=a["load_factor"], fixed_mu=a["prescribed"],
        q0=scenes.scene_start_state(scene, structure), eigenvalue_column=c["eigenvalue_column"],
        critical_rtol=c["critical_rtol"],
    )
    if c["initial_increment"] is not None:
        options["initial_increment"] = c["initial_increment"]
    if c["max_displacement"] is not None:
        options["max_displacement"] = c["max_displacement"]
    monitor, event_x = None, None
    if c["monitor_node"] is not None:
        monitor = f"u{c['monitor_component']}{c['monitor_node']}"
        dof = 3 * c["monitor_node"] + AXES[c["monitor_component"]]
        options["monitors"] = {monitor: dof}
        event_x = lambda e: e.q[dof] - system.q_ref[dof]  # noqa: E731 (the plot's abscissa of an event)
    return options, monitor, event_x


def run_continuation(scene: dict, out: Path, progress: Progress, resume: bool = False) -> dict:
    return trace_model(scene, build_scene_model(scene, progress), out, progress, resume)


def trace_model(scene: dict, model, out: Path, progress: Progress, resume: bool = False, **overrides) -> dict:
    """Trace the path of a built scene model and write its files; returns the summary.

    ``overrides`` are further ``trace_path`` options (an imperfection study's step control).
    """
    structure, system = model.structure, model.system
    a = scene["analysis"]
    c = a["continuation"]
    control = c["control"]
    options, monitor, event_x = path_options(scene, structure, system)
    options.update(overrides)

    progress(
        f"continuation ({control} control): {structure.n_nodes} nodes, {system.n_free} free DOFs, "
        f"effects: {', '.join(e.name for e in system.effects)}"
    )
    plot = PathPlot("load_displacement.png", x=monitor or "displacement",
                    xlabel=f"displacement {monitor or ''} [m]".replace("  ", " "),
                    ylabel="load factor" if control == "load" else "reaction conjugate to the prescribed motion [N]",
                    title=scene["title"], event_x=event_x)
    res, path_summary = run_continuation_case(
        system, out, control, PathFiles("path", plot, c["checkpoint_every"], resume), progress=indented(progress),
        **options)
    for e in res.events:
        progress(f"  {e.kind} point at parameter {e.parameter:.6g}, load {e.load:.6g} (step {e.step})")
    lam_of = dict(zip(res.table["step"], res.table["lam"]))
    time_name = write_path_series(out / "path.xdmf", system, res, a["load_factor"])
    final = []
    if res.states:
        with evaluated_with(system, res.state_histories[-1] if res.state_histories else None):
            final = write_final_state(scene, out, system, res.states[-1],
                                      lam_of.get(res.state_steps[-1], a["load_factor"]),
                                      [f for f in scene["output"]["formats"] if f != "xdmf"])
    summary = {"analysis": "continuation", "converged": bool(res.success), **path_summary,
               **model_sizes(structure, system)}
    summary["files"] = path_summary["files"] + ["path.xdmf", "path.h5"] + final
    summary["xdmf_time"] = time_name
    if model.imperfection:
        summary["imperfection"] = model.imperfection
    weak = _below_the_loads(res, control)
    if weak:
        summary["warnings"] = summary.get("warnings", []) + [weak]
    return summary


def _below_the_loads(res, control: str) -> str | None:
    """Under load control, a first critical point below load factor 1: the structure does not carry its loads."""
    first = res.events[0] if res.events else None
    if control != "load" or first is None or not 0.0 <= first.lam < 1.0:
        return None
    return (f"the structure loses stability under {first.lam:.3g} times its loads, less than the loads "
            f"themselves ({first.kind} point at load factor {first.lam:.4g} < 1)")
