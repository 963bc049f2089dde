"""Apex indentation of the hemispherical gridshell scene."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .. import scene as scenes
from ..io import write_series, write_state
from ..io.table import CurveStyle, plot_curve, write_csv
from ..scene.schema import check_table
from ..progress import Progress, Status
from .common import plot_or_note, series_time, write_final_state


def hemisphere_model(scene: dict):
    """The hemisphere of a validated scene (the paper's values where [rods] leaves them open)."""
    from ..gridshell.hemisphere import PAPER, HemisphereSpec, build_hemisphere

    g = scene["geometry"]
    rods = scene["rods"] or check_table("rods", {}, scenes.SCENE.keys["rods"])

    def pick(key, paper):
        return PAPER[paper] if rods[key] is None else rods[key]

    return build_hemisphere(HemisphereSpec(
        g["n"], radius=g["radius"] or PAPER["radius"], voronoi_length=g["voronoi_length"],
        rod_radius=pick("radius", "rod_radius"), youngs_modulus=pick("E", "youngs_modulus"),
        shear_modulus=rods["G"], density=pick("density", "density"), joints=rods["joints"] or "penalty",
        stiffness_ratio=rods["joint_stiffness_ratio"],
    ))


def run_indentation(scene: dict, out: Path, progress: Progress, resume: bool = False) -> dict:
    from ..gridshell.hemisphere import prestress_on_net
    from ..gridshell.configurations import classify_configuration
    from ..gridshell.indentation import indentation_system, trace_indentation

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
        progress(Status(f"  dD/R {x: .4f}  force R^2/EI {y: .5g}  negative eigenvalues {n_negative}",
                        x / ind["max_displacement"]))

    res = trace_indentation(setup, dD_max=ind["max_displacement"] * R, increment=ind["increment"],
                            snap_method=ind["snap_method"], max_snaps=ind["max_snaps"], max_steps=ind["max_steps"],
                            store_states=True, progress=report)
    progress(res.message)
    for k, s in enumerate(res.snaps):
        progress(f"  snap {k + 1} at dD/R = {s.dD_over_R:.4f}: {s.label_before} -> {s.label_after}")
    table = {"dD": res.dD, "dD_over_R": res.x, "force": res.force, "force_normalised": res.y,
             "segment": res.segment, "n_negative": res.n_negative, "label": res.labels}
    units = {"dD": "m", "dD_over_R": "-", "force": "N", "force_normalised": "-", "segment": "-", "n_negative": "-"}
    files = [write_csv(out / "indentation.csv", table, units=units).name]
    notes: list[str] = []
    plot_or_note(out / "indentation.png", lambda: plot_curve(
        out / "indentation.png", res.x, res.y, "apex displacement dD / R", "indentation force -sum(Fz) R^2 / EI",
        scene["title"] or f"hemisphere, mode {ind['mode']}",
        CurveStyle(marks=[(s.dD_over_R, s.force_before, f"snap {k + 1}") for k, s in enumerate(res.snaps)],
                   branch=res.segment, branch_name="segment")), files, notes)
    name, times = series_time(("apex displacement dD/R", res.x), ("state", np.arange(len(res.path_states))))
    # every state with the rod frames it was found with (the end's frames give other twists and forces)
    write_series(out / "indentation.xdmf", system,
                 [(t, q, 1.0, h) for t, q, h in zip(times, res.path_states, res.path_histories)], time_name=name)
    files += ["indentation.xdmf", "indentation.h5"]
    configurations = []
    # the pre-stressed start, then the states the tracer kept: segment ends, critical points, landings
    states = ([(0.0, res.path_states[0], res.path_histories[0])]
              + [(x, q, res.state_histories.get(x)) for x, q in sorted(res.states.items())] if res.path_states else [])
    for k, (x, q, history) in enumerate(states):
        name = f"configuration_{k:02d}.vtu"
        write_state(out / name, system, q, history=history)
        configurations.append({"file": name, "dD_over_R": float(x), "label": classify_configuration(model, q)})
        files.append(name)
    if res.path_states:
        # a run that stops at an unstable point has accepted it after the last state of the path
        with system.evaluated_with(res.path_histories[-1]):
            files += write_final_state(scene, out, system, res.path_states[-1], 1.0,
                                       [f for f in scene["output"]["formats"] if f != "xdmf"])
    summary = {**base, "converged": bool(res.success), **res.summary(), "mode": ind["mode"],
               "imperfection": {"type": "forces", "amplitude_N": float(amplitude),
                                "amplitude_over_EI_R2": float(amplitude / scale), "seed": int(seed)},
               "force_scale_N": float(scale), "configurations": configurations}
    summary["files"] = files
    if notes:
        summary["warnings"] = notes
    return summary
