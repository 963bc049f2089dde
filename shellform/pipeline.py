"""From a validated scene to results on disk."""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from . import scene as scenes
from .io import write_json, write_series, write_state
from .io.table import plot_curve, write_csv
from .model import AXES
from .solvers import solve_static

Progress = Callable[[str], None]


def _quiet(message: str) -> None:
    pass


def _start_state(scene, structure):
    start = scene["analysis"]["start"]
    if start is None:
        return None
    q0 = structure.reference_state()
    q0[: 3 * structure.n_nodes] = start.ravel()
    return q0


def _sizes(structure, system) -> dict:
    return {
        "n_nodes": structure.n_nodes,
        "n_members": int(sum(g.n_members for g in structure.groups)),
        "n_dof": structure.n_dof,
        "n_free_dof": system.n_free,
        "effects": [e.name for e in system.effects],
    }


def run_static(scene: dict, out: Path, progress: Progress, resume: bool = False) -> dict:
    structure = scenes.build_structure(scene)
    system = scenes.build_system(scene, structure)
    a = scene["analysis"]
    q0 = _start_state(scene, structure)
    progress(
        f"static analysis: {structure.n_nodes} nodes, {sum(g.n_members for g in structure.groups)} members, "
        f"{system.n_free} free DOFs, effects: {', '.join(e.name for e in system.effects)}"
    )
    res = solve_static(
        system, q0=q0, lam=a["load_factor"], mu=a["prescribed"], rtol=a["rtol"], max_iter=a["max_iterations"],
        merit=a["merit"], linear_solver=a["linear_solver"],
        callback=lambda it, norm: progress(f"  iteration {it:3d}  |r| = {norm:.3e}"),
    )
    progress(res.message)
    files = []
    for fmt in scene["output"]["formats"]:
        path = out / f"state.{fmt}"
        if fmt == "xdmf":
            write_series(path, system, [(a["load_factor"], res.q, a["load_factor"])])
        elif fmt == "3dm":
            from .io.rhino import structure_3dm

            structure_3dm(path, system, res.q)
        else:
            write_state(path, system, res.q, a["load_factor"])
        files.append(path.name)
    x = res.q[: 3 * structure.n_nodes].reshape(-1, 3)
    R = res.reactions[: 3 * structure.n_nodes].reshape(-1, 3)
    return {
        "analysis": "static",
        "converged": bool(res.success),
        "message": res.message,
        "iterations": res.iterations,
        "residual_norm": res.residual_norm,
        "tolerance": res.tolerance,
        "load_factor": a["load_factor"],
        **_sizes(structure, system),
        "max_displacement": float(np.linalg.norm(x - structure.nodes, axis=1).max()),
        "reaction_sum": R.sum(axis=0),
        "files": files,
    }


def run_continuation(scene: dict, out: Path, progress: Progress, resume: bool = False) -> dict:
    from .solvers.continuation import TABLE_COLUMNS, trace_path

    structure = scenes.build_structure(scene)
    system = scenes.build_system(scene, structure)
    a = scene["analysis"]
    c = a["continuation"]
    control = c["control"]
    options = dict(
        max_steps=c["max_steps"], parameter_bounds=(c["parameter_min"], c["parameter_max"]),
        constraint=c["constraint"], stability=c["stability"], on_bifurcation=c["on_bifurcation"],
        branch_side=c["branch_side"], rtol=a["rtol"], fixed_lam=a["load_factor"], fixed_mu=a["prescribed"],
    )
    if c["initial_increment"] is not None:
        options["initial_increment"] = c["initial_increment"]
    if c["max_displacement"] is not None:
        options["max_displacement"] = c["max_displacement"]
    monitor = None
    if c["monitor_node"] is not None:
        monitor = f"u{c['monitor_component']}{c['monitor_node']}"
        options["monitors"] = {monitor: 3 * c["monitor_node"] + AXES[c["monitor_component"]]}
    progress(
        f"continuation ({control} control): {structure.n_nodes} nodes, {system.n_free} free DOFs, "
        f"effects: {', '.join(e.name for e in system.effects)}"
    )

    def report(point):
        progress(
            f"  step {point.step:4d}  parameter {point.parameter: .5g}  load {point.load: .5g}  "
            f"displacement {point.displacement: .5g}  negative eigenvalues {point.n_negative}  "
            f"iterations {point.iterations}"
        )

    checkpoint = out / "checkpoint.npz"
    res = trace_path(
        system, control=control, q0=_start_state(scene, structure), callback=report, checkpoint=checkpoint,
        checkpoint_every=c["checkpoint_every"], resume=resume, **options,
    )
    progress(res.message)
    for e in res.events:
        progress(f"  {e.kind} point at parameter {e.parameter:.6g}, load {e.load:.6g} (step {e.step})")
    table = res.table
    columns = list(TABLE_COLUMNS) + list(res.monitors)
    write_csv(out / "path.csv", table, columns)
    lam_of = dict(zip(table["step"], table["lam"]))
    write_series(out / "path.xdmf", system, [(step, q, lam_of.get(step, a["load_factor"]))
                                             for step, q in zip(res.state_steps, res.states)])
    x = table[monitor] if monitor else table["displacement"]
    marks = [((e.q[options["monitors"][monitor]] - system.q_ref[options["monitors"][monitor]]) if monitor
              else e.displacement, e.load, e.kind) for e in res.events]
    plot_curve(
        out / "load_displacement.png", x, table["load"],
        xlabel=f"displacement {monitor or ''} [m]".replace("  ", " "),
        ylabel="load factor" if control == "load" else "reaction conjugate to the prescribed motion [N]",
        title=scene["title"], marks=marks, stable=np.asarray(table["n_negative"]) == 0 if c["stability"] else None,
    )
    summary = {"analysis": "continuation", "converged": bool(res.success), **res.summary(), **_sizes(structure, system)}
    summary["files"] = ["path.csv", "path.xdmf", "load_displacement.png", "checkpoint.npz"]
    return summary


def run_form_finding(scene: dict, out: Path, progress: Progress, resume: bool = False) -> dict:
    from .mra.case import run_mra_case

    summary = run_mra_case(scene["mra"], out, progress)
    summary.setdefault("analysis", "mra")
    return summary


def run_form_and_buckling(scene: dict, out: Path, progress: Progress, resume: bool = False) -> dict:
    from .formbuckle import run_form_and_buckle

    summary = run_form_and_buckle(scene["mra"], out, progress)
    summary.setdefault("analysis", "form_and_buckle")
    return summary


ANALYSES = {"static": run_static, "continuation": run_continuation, "mra": run_form_finding,
            "form_and_buckle": run_form_and_buckling}


def run_scene(scene: dict, out_dir, progress: Progress | None = None, resume: bool = False) -> dict:
    """Run a validated scene and write ``summary.json`` and meshes to ``out_dir``.

    The summary is written even when the analysis does not converge (with
    ``converged = false`` and the solver's message), so a failed run still
    says what happened. ``resume`` continues an interrupted continuation from
    the checkpoint in ``out_dir``.
    """
    progress = progress or _quiet
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    summary = {"title": scene["title"]}
    summary.update(ANALYSES[scene["analysis"]["type"]](scene, out, progress, resume))
    summary["wall_time_s"] = time.perf_counter() - t0
    write_json(out / "summary.json", summary)
    return summary
