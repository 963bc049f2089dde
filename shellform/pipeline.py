"""From a validated scene to results on disk: one runner per analysis.

Every runner returns a JSON-ready summary (``run_scene`` writes it to
``summary.json``, also when the analysis did not converge) and writes its
files through :mod:`shellform.io`. ``summary.json`` is written as the run
starts and as each of its stages starts and ends (``stages``,
``run_status``), so a run killed half-way never leaves a summary claiming
success. One run at a time holds an output folder. Long analyses keep a
checkpoint in the output folder and continue from it with ``resume=True``;
a checkpoint of another model or other settings is refused.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from . import scene as scenes
from .errors import SceneError
from .io import write_json, write_series, write_state
from .io.checkpoint import (CheckpointMismatch, check_fingerprint, fingerprint_record, load_checkpoint,
                            model_fingerprint, save_checkpoint)
from .io.files import output_folder, output_lock, remove_stale_temporaries, write_bytes
from .io.summary import RunRecord
from .io.table import plot_curve, plot_path, write_csv, write_path_csv
from .model import AXES
from .schema import check_table
from .solvers import solve_static

Progress = Callable[[str], None]


def _quiet(message: str) -> None:
    pass


def _sizes(structure, system) -> dict:
    return {
        "n_nodes": structure.n_nodes,
        "n_members": int(sum(g.n_members for g in structure.groups)),
        "n_dof": structure.n_dof,
        "n_free_dof": system.n_free,
        "effects": [e.name for e in system.effects],
    }


def _plot(path: Path, draw: Callable[[], Path], files: list, notes: list) -> None:
    """Draw a plot (``draw()`` writes ``path``); a plot that fails is noted, not raised.

    A plot only pictures results already on disk; failing the run over it,
    after the analysis, would lose the summary instead.
    """
    try:
        files.append(draw().name)
    except Exception as exc:  # noqa: BLE001 (whatever Matplotlib raised goes to the summary)
        notes.append(f"plot {path.name} not drawn: {type(exc).__name__}: {exc}")


def _write_final(scene: dict, out: Path, system, q, lam: float, formats=None) -> list[str]:
    """The final state in the scene's output formats (``state.<format>``)."""
    files = []
    for fmt in formats if formats is not None else scene["output"]["formats"]:
        path = out / f"state.{fmt}"
        if fmt == "xdmf":
            write_series(path, system, [(lam, q, lam)])
        elif fmt == "3dm":
            from .io.rhino import structure_3dm

            structure_3dm(path, system, q)
        else:
            write_state(path, system, q, lam)
        files.append(path.name)
    return files


def _model(scene: dict, progress: Progress):
    model = scenes.build_model(scene)
    if model.imperfection:
        progress("imperfection: " + ", ".join(f"{k} {v}" for k, v in model.imperfection.items()))
    return model


def run_static(scene: dict, out: Path, progress: Progress, resume: bool = False) -> dict:
    model = _model(scene, progress)
    structure, system = model.structure, model.system
    a = scene["analysis"]
    progress(
        f"static analysis: {structure.n_nodes} nodes, {sum(g.n_members for g in structure.groups)} members, "
        f"{system.n_free} free DOFs, effects: {', '.join(e.name for e in system.effects)}"
    )
    res = solve_static(
        system, q0=scenes.start_state(scene, structure), lam=a["load_factor"], mu=a["prescribed"], rtol=a["rtol"],
        max_iter=a["max_iterations"], merit=a["merit"], linear_solver=a["linear_solver"],
        callback=lambda it, norm: progress(f"  iteration {it:3d}  |r| = {norm:.3e}"),
    )
    progress(res.message)
    files = _write_final(scene, out, system, res.q, a["load_factor"])
    x = res.q[: 3 * structure.n_nodes].reshape(-1, 3)
    R = res.reactions[: 3 * structure.n_nodes].reshape(-1, 3)
    summary = {
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
    if model.imperfection:
        summary["imperfection"] = model.imperfection
    return summary


def run_continuation_case(
    system,
    out_dir,
    control: str = "load",
    name: str = "path",
    progress: Progress | None = None,
    resume: bool = True,
    checkpoint_every: int = 10,
    plot_file: str | None = "",
    x: str = "displacement",
    xlabel: str | None = None,
    ylabel: str | None = None,
    title: str | None = None,
    event_x=None,
    callback=None,
    **options,
):
    """Trace a path and write its files to ``out_dir``.

    Writes ``{name}.csv`` (path table), the force-displacement plot
    (``plot_file``, default ``{name}.png``; None: no plot), ``{name}_events.json``
    (outcome and events) and keeps ``{name}_checkpoint.npz``: started again
    with the same arguments, an interrupted run resumes from its last
    checkpoint.

    Parameters
    ----------
    system : System
    out_dir : path-like
        Created if missing.
    control : {"load", "displacement"}
    name : str
        Stem of the file names.
    progress : callable, optional
        Receives one line of text per converged point.
    resume : bool
        Continue from an existing checkpoint.
    checkpoint_every : int
        Steps between checkpoints.
    x, xlabel, ylabel, title, event_x
        The plot: abscissa column (a monitor or ``displacement``), labels and
        the abscissa of an event when ``x`` is a monitor (see
        :func:`~shellform.io.table.plot_path`).
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
    from .solvers.continuation import trace_path

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    ck = out / f"{name}_checkpoint.npz"

    def on_point(pt):
        if progress is not None:
            progress(
                f"step {pt.step:4d}  branch {pt.branch}  parameter {pt.parameter: .6e}  load {pt.load: .6e}  "
                f"displacement {pt.displacement: .6e}  negative eigenvalues {pt.n_negative}  "
                f"iterations {pt.iterations}"
            )
        return callback(pt) if callback is not None else None

    result = trace_path(system, control, callback=on_point, checkpoint=ck, checkpoint_every=checkpoint_every,
                        resume=resume, **options)
    files = [write_path_csv(result, out / f"{name}.csv").name]
    summary = result.summary()
    summary["files"] = files + [f"{name}_events.json", ck.name]
    # the outcome is on disk before the plot is drawn
    write_json(out / f"{name}_events.json", summary)
    if plot_file is not None:
        default_y = "load factor" if control == "load" else "reaction conjugate to the prescribed displacement"
        plots, notes = [], []
        png = out / (plot_file or f"{name}.png")
        _plot(png, lambda: plot_path(result, png, x=x, xlabel=xlabel or x, ylabel=ylabel or default_y, title=title,
                                     event_x=event_x), plots, notes)
        summary["files"] = files + plots + summary["files"][1:]
        if notes:
            summary["warnings"] = notes
            for note in notes:
                if progress is not None:
                    progress(note)
        write_json(out / f"{name}_events.json", summary)
    if progress is not None:
        progress(f"{result.message} ({result.steps} steps, {len(result.events)} events)")
    return result, summary


def run_continuation(scene: dict, out: Path, progress: Progress, resume: bool = False) -> dict:
    model = _model(scene, progress)
    structure, system = model.structure, model.system
    a = scene["analysis"]
    c = a["continuation"]
    control = c["control"]
    options = dict(
        max_steps=c["max_steps"], parameter_bounds=(c["parameter_min"], c["parameter_max"]),
        constraint=c["constraint"], stability=c["stability"], on_bifurcation=c["on_bifurcation"],
        branch_side=c["branch_side"], rtol=a["rtol"], fixed_lam=a["load_factor"], fixed_mu=a["prescribed"],
        q0=scenes.start_state(scene, structure),
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

    progress(
        f"continuation ({control} control): {structure.n_nodes} nodes, {system.n_free} free DOFs, "
        f"effects: {', '.join(e.name for e in system.effects)}"
    )
    res, path_summary = run_continuation_case(
        system, out, control, name="path", progress=lambda msg: progress("  " + msg), resume=resume,
        checkpoint_every=c["checkpoint_every"], plot_file="load_displacement.png", x=monitor or "displacement",
        xlabel=f"displacement {monitor or ''} [m]".replace("  ", " "),
        ylabel="load factor" if control == "load" else "reaction conjugate to the prescribed motion [N]",
        title=scene["title"], event_x=event_x, **options,
    )
    for e in res.events:
        progress(f"  {e.kind} point at parameter {e.parameter:.6g}, load {e.load:.6g} (step {e.step})")
    lam_of = dict(zip(res.table["step"], res.table["lam"]))
    write_series(out / "path.xdmf", system, [(step, q, lam_of.get(step, a["load_factor"]))
                                             for step, q in zip(res.state_steps, res.states)])
    final = _write_final(scene, out, system, res.states[-1], lam_of.get(res.state_steps[-1], a["load_factor"]),
                         [f for f in scene["output"]["formats"] if f != "xdmf"]) if res.states else []
    summary = {"analysis": "continuation", "converged": bool(res.success), **path_summary,
               **_sizes(structure, system)}
    summary["files"] = path_summary["files"] + ["path.xdmf"] + final
    if model.imperfection:
        summary["imperfection"] = model.imperfection
    return summary


# -- time stepping ------------------------------------------------------------------------------


DYNAMICS_CHECKPOINT = "dynamics_checkpoint.npz"


def _load_factor_of(scene: dict):
    lam = scene["analysis"]["load_factor"]
    ramp = scene["analysis"]["dynamics"]["ramp_time"]
    if ramp > 0:
        return lambda t: lam * min(t / ramp, 1.0)
    return lambda t: lam


def run_dynamics(scene: dict, out: Path, progress: Progress, resume: bool = False) -> dict:
    from .solvers.implicit_euler import implicit_euler, lumped_mass

    model = _model(scene, progress)
    structure, system = model.structure, model.system
    a, d = scene["analysis"], scene["analysis"]["dynamics"]
    mass = lumped_mass(structure)
    if not np.any(mass[system.free] > 0):
        raise SceneError("members", "time stepping needs mass at the free nodes: give the members a "
                         "mass_per_length or [masses] node_mass")
    lam = _load_factor_of(scene)
    n = structure.n_nodes
    monitor = None
    if d["monitor_node"] is not None:
        monitor = (f"u{d['monitor_component']}{d['monitor_node']}",
                   3 * d["monitor_node"] + AXES[d["monitor_component"]])
    columns = ["step", "time", "kinetic_energy", "max_displacement"] + ([monitor[0]] if monitor else [])
    history = {c: [] for c in columns}
    q0 = system.state(base=scenes.start_state(scene, structure))
    t0, v0, step = 0.0, None, 0
    frames = [(0.0, q0.copy(), lam(0.0))]
    ck_path = out / DYNAMICS_CHECKPOINT
    # what the motion depends on: the model with its masses, and every setting but the end time
    # (a resumed run may go on further) and how often a checkpoint is written
    fingerprint = model_fingerprint(system, mass=mass)
    settings = {k: v for k, v in d.items() if k not in ("duration", "checkpoint_interval")}
    settings.update(load_factor=a["load_factor"], prescribed=a["prescribed"], linear_solver=a["linear_solver"],
                    start=scenes.start_state(scene, structure))
    saved = load_checkpoint(ck_path) if resume else None
    if saved is not None:
        if saved["q"].shape != q0.shape:
            raise CheckpointMismatch(f"{ck_path} holds a state of {saved['q'].size} DOFs; this scene has "
                                     f"{q0.size}: delete it or run without --resume")
        check_fingerprint(ck_path, json.loads(str(saved["fingerprint"])) if "fingerprint" in saved else None,
                          fingerprint, settings)
        t0, q0, v0, step = float(saved["t"]), saved["q"], saved["v"], int(saved["step"])
        history = {c: list(saved[f"history_{c}"]) for c in columns}
        frames = [(float(t), q, lam(float(t))) for t, q in zip(saved["frame_t"], saved["frame_q"])]
        progress(f"resuming the time stepping at t = {t0:.6g} s (step {step}) from {ck_path.name}")
    elif resume:
        progress(f"no checkpoint in {out}: starting at t = 0")
    state = {"step": step, "last": time.perf_counter()}

    def save(t, q, v):
        save_checkpoint(ck_path, t=t, q=q, v=v, step=state["step"],
                        fingerprint=fingerprint_record(fingerprint, settings),
                        frame_t=[f[0] for f in frames], frame_q=np.array([f[1] for f in frames]),
                        **{f"history_{c}": np.asarray(history[c]) for c in columns})
        state["last"] = time.perf_counter()

    def record(t, q, v, count=True):
        state["step"] += count
        x = q[: 3 * n].reshape(-1, 3)
        row = [state["step"], t, 0.5 * float(v @ (mass * v)), float(np.linalg.norm(x - structure.nodes, axis=1).max())]
        if monitor:
            row.append(float(q[monitor[1]] - system.q_ref[monitor[1]]))
        for c, value in zip(columns, row):
            history[c].append(value)
        if count and state["step"] % d["output_every"] == 0:
            frames.append((t, q.copy(), lam(t)))
        if time.perf_counter() - state["last"] >= d["checkpoint_interval"]:
            save(t, q, v)

    if saved is None:
        record(t0, q0, np.zeros_like(q0), count=False)
    progress(f"time stepping: {n} nodes, {system.n_free} free DOFs, h = {d['time_step']} s up to "
             f"t = {d['duration']} s, damping {d['damping']} 1/s")
    if t0 < d["duration"] * (1 - 1e-12):
        res = implicit_euler(system, d["time_step"], d["duration"], q0=q0, v0=v0, mass=mass, damping=d["damping"],
                             lam=lam, mu=a["prescribed"], t0=t0, linear_solver=a["linear_solver"], callback=record)
        q_end, v_end, t_end = res.q, res.v, res.t
        success, message = res.success, res.message
        steps, rejected = res.steps, res.rejected_steps
        newton = int(sum(res.newton_iterations))
    else:
        q_end, v_end, t_end = q0, v0, t0
        success, message, steps, rejected, newton = True, f"reached t = {t0:.6g} s (from the checkpoint)", 0, 0, 0
    progress(message)
    save(t_end, q_end, v_end if v_end is not None else np.zeros_like(q_end))
    if frames[-1][0] != t_end:
        frames.append((t_end, q_end.copy(), lam(t_end)))
    files = [write_csv(out / "dynamics.csv", history, columns).name]
    write_series(out / "dynamics.xdmf", system, frames)
    files.append("dynamics.xdmf")
    y = monitor[0] if monitor else "max_displacement"
    notes: list[str] = []
    _plot(out / "dynamics.png", lambda: plot_curve(out / "dynamics.png", history["time"], history[y], "time [s]",
                                                   f"{y} [m]", scene["title"]), files, notes)
    files += _write_final(scene, out, system, q_end, lam(t_end),
                          [f for f in scene["output"]["formats"] if f != "xdmf"])
    files.append(DYNAMICS_CHECKPOINT)
    r = system.residual(q_end, lam(t_end))
    summary = {
        "analysis": "dynamics",
        "converged": bool(success),
        "message": message,
        "time": float(t_end),
        "steps": int(state["step"]),
        "steps_this_run": int(steps),
        "rejected_steps": int(rejected),
        "newton_iterations": newton,
        "frames": len(frames),
        "kinetic_energy": float(history["kinetic_energy"][-1]) if history["kinetic_energy"] else 0.0,
        "static_residual_norm": float(np.linalg.norm(r[system.free])),
        "max_displacement": float(np.linalg.norm(q_end[: 3 * n].reshape(-1, 3) - structure.nodes, axis=1).max()),
        **_sizes(structure, system),
        "files": files,
    }
    if notes:
        summary["warnings"] = notes
    if model.imperfection:
        summary["imperfection"] = model.imperfection
    return summary


# -- the hemispherical gridshell ----------------------------------------------------------------


def hemisphere_model(scene: dict):
    """The hemisphere of a validated scene (the paper's values where [rods] leaves them open)."""
    from .gridshell.hemisphere import PAPER, build_hemisphere

    g = scene["geometry"]
    rods = scene["rods"] or check_table("rods", {}, scenes.SCENE.keys["rods"])

    def pick(key, paper):
        return PAPER[paper] if rods[key] is None else rods[key]

    return build_hemisphere(
        g["n"], radius=g["radius"] or PAPER["radius"], voronoi_length=g["voronoi_length"],
        rod_radius=pick("radius", "rod_radius"), youngs_modulus=pick("E", "youngs_modulus"),
        shear_modulus=rods["G"], density=pick("density", "density"), joints=rods["joints"],
        stiffness_ratio=rods["joint_stiffness_ratio"],
    )


def run_indentation(scene: dict, out: Path, progress: Progress, resume: bool = False) -> dict:
    from .gridshell.hemisphere import prestress_on_net
    from .gridshell.configurations import classify_configuration
    from .gridshell.indentation import indentation_system, trace_indentation

    if resume:
        progress("the indentation keeps no checkpoint: starting over")
    ind = scene["analysis"]["indentation"]
    model = hemisphere_model(scene)
    R = model.radius
    progress(f"hemisphere: n = {model.n}, R = {R:.4g} m, {model.structure.n_nodes} nodes, "
             f"{len(model.network.rods)} rods; pre-stress on the net")
    pre = prestress_on_net(model)
    progress(pre.message)
    base = {"analysis": "indentation", "n": model.n, "radius": R, "n_nodes": model.structure.n_nodes,
            "prestress": {"success": bool(pre.success), "iterations": int(pre.iterations),
                          "wall_time_s": float(pre.wall_time_s),
                          "apex_height_over_R": float(model.positions(pre.q)[model.apex_nodes, 2].mean() / R)}}
    if not pre.success:
        return {**base, "converged": False, "message": f"pre-stress failed: {pre.message}", "files": []}
    imp = scene["imperfection"]
    scale = model.EI / R**2
    amplitude = 1.0e-4 * scale if imp is None else imp["amplitude"]
    seed = 0 if imp is None else imp["seed"]
    setup = indentation_system(model, pre, mode=ind["mode"], imperfection=amplitude / scale, seed=seed)
    system = setup.system

    def report(x, y, n_negative):
        progress(f"  dD/R {x: .4f}  force R^2/EI {y: .5g}  negative eigenvalues {n_negative}")

    res = trace_indentation(setup, dD_max=ind["max_displacement"] * R, increment=ind["increment"],
                            snap_method=ind["snap_method"], max_snaps=ind["max_snaps"], max_steps=ind["max_steps"],
                            store_states=True, progress=report)
    progress(res.message)
    for k, s in enumerate(res.snaps):
        progress(f"  snap {k + 1} at dD/R = {s.dD_over_R:.4f}: {s.label_before} -> {s.label_after}")
    table = {"dD": res.dD, "dD_over_R": res.x, "force": res.force, "force_normalised": res.y,
             "segment": res.segment, "n_negative": res.n_negative, "label": res.labels}
    files = [write_csv(out / "indentation.csv", table).name]
    notes: list[str] = []
    _plot(out / "indentation.png", lambda: plot_curve(
        out / "indentation.png", res.x, res.y, "apex displacement dD / R", "indentation force -sum(Fz) R^2 / EI",
        scene["title"] or f"hemisphere, mode {ind['mode']}",
        marks=[(s.dD_over_R, s.force_before, f"snap {k + 1}") for k, s in enumerate(res.snaps)],
        branch=res.segment, branch_name="segment"), files, notes)
    write_series(out / "indentation.xdmf", system, [(x, q, 1.0) for x, q in zip(res.x, res.path_states)])
    files.append("indentation.xdmf")
    configurations = []
    # the pre-stressed start, then the states the tracer kept: segment ends, critical points, landings
    states = [(0.0, res.path_states[0])] + sorted(res.states.items()) if res.path_states else []
    for k, (x, q) in enumerate(states):
        name = f"configuration_{k:02d}.vtu"
        write_state(out / name, system, q)
        configurations.append({"file": name, "dD_over_R": float(x), "label": classify_configuration(model, q)})
        files.append(name)
    if res.path_states:
        files += _write_final(scene, out, system, res.path_states[-1], 1.0,
                              [f for f in scene["output"]["formats"] if f != "xdmf"])
    summary = {**base, "converged": bool(res.success), **res.summary(), "mode": ind["mode"],
               "imperfection": {"type": "forces", "amplitude_N": float(amplitude),
                                "amplitude_over_EI_R2": float(amplitude / scale), "seed": int(seed)},
               "force_scale_N": float(scale), "configurations": configurations}
    summary["files"] = files
    if notes:
        summary["warnings"] = notes
    return summary


# -- dispatch ---------------------------------------------------------------------------------


def run_form_finding(scene: dict, out: Path, progress: Progress, resume: bool = False,
                     record: RunRecord | None = None) -> dict:
    from .formbuckle import run_form_finding as run

    return run(scene, out, progress, resume)


def run_form_and_buckling(scene: dict, out: Path, progress: Progress, resume: bool = False,
                          record: RunRecord | None = None) -> dict:
    from .formbuckle import run_form_and_buckle

    return run_form_and_buckle(scene, out, progress, resume, record=record)


ANALYSES = {"static": run_static, "continuation": run_continuation, "dynamics": run_dynamics,
            "mra": run_form_finding, "form_and_buckle": run_form_and_buckling, "indentation": run_indentation}

#: the stages of each analysis, in order; a runner of more than one reports them itself
STAGES = {"static": ("static",), "continuation": ("continuation",), "dynamics": ("time_stepping",),
          "mra": ("form_finding",), "form_and_buckle": ("form_finding", "buckling"),
          "indentation": ("indentation",)}


def run_scene(scene: dict, out_dir, progress: Progress | None = None, resume: bool = False) -> dict:
    """Run a validated scene and write ``summary.json`` and its result files to ``out_dir``.

    The summary is written when the run starts (``run_status = "running"``), as
    each stage starts and ends, and at the end, also when the analysis does
    not converge or fails (with ``converged = false`` and the message), so
    the summary of a run that was killed never claims success. Its
    ``stages`` say how far the run got; ``converged`` is true only when every
    stage finished and converged. ``resume`` continues an interrupted
    continuation, relaxation or time stepping from the checkpoint in
    ``out_dir``.

    The output folder is locked for the run: a second run into it is refused.

    Raises
    ------
    OutputError
        ``out_dir`` is a file, or another run holds it.
    """
    progress = progress or _quiet
    kind = scene["analysis"]["type"]
    stages = STAGES[kind]
    with output_lock(output_folder(out_dir)) as out:
        remove_stale_temporaries(out)  # of a run killed while writing: no one else writes here now
        t0 = time.perf_counter()
        record = RunRecord(out / "summary.json", {"title": scene["title"], "analysis": kind}, stages)
        last = out / "summary.json"
        previous = last.read_bytes() if last.is_file() and not last.is_symlink() else None
        if len(stages) == 1:
            record.start(stages[0])
        else:
            record.write()
        try:
            if len(stages) == 1:
                summary = ANALYSES[kind](scene, out, progress, resume)
                record.finish(stages[0], bool(summary.get("converged", False)), summary.get("message"))
            else:
                summary = ANALYSES[kind](scene, out, progress, resume, record=record)
        except CheckpointMismatch as exc:
            # refused before anything was computed: the folder stays as the last run left it
            if previous is not None:
                write_bytes(out / "summary.json", previous)
            else:
                record.stop("failed", str(exc))
            raise
        except KeyboardInterrupt:
            record.stop("interrupted", "interrupted; `shellform run ... --resume` continues from the last checkpoint")
            raise
        except BaseException as exc:
            record.stop("failed", f"{type(exc).__name__}: {exc}")
            raise
        summary = {"title": scene["title"], **summary}
        summary["wall_time_s"] = time.perf_counter() - t0
        record.write(summary)
        return {**summary, "run_status": record.status, "converged": record.converged, "stages": record.stages}
