"""From a validated scene to results on disk."""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from . import scene as scenes
from .io import write_json, write_series, write_state
from .solvers import solve_static

Progress = Callable[[str], None]


def _quiet(message: str) -> None:
    pass


def run_static(scene: dict, out: Path, progress: Progress) -> dict:
    structure = scenes.build_structure(scene)
    system = scenes.build_system(scene, structure)
    a = scene["analysis"]
    q0 = None
    if a["start"] is not None:
        q0 = structure.reference_state()
        q0[: 3 * structure.n_nodes] = a["start"].ravel()
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
        "n_nodes": structure.n_nodes,
        "n_members": int(sum(g.n_members for g in structure.groups)),
        "n_dof": structure.n_dof,
        "n_free_dof": system.n_free,
        "effects": [e.name for e in system.effects],
        "max_displacement": float(np.linalg.norm(x - structure.nodes, axis=1).max()),
        "reaction_sum": R.sum(axis=0),
        "files": files,
    }


ANALYSES = {"static": run_static}


def run_scene(scene: dict, out_dir, progress: Progress | None = None) -> dict:
    """Run a validated scene and write ``summary.json`` and meshes to ``out_dir``.

    The summary is written even when the analysis does not converge (with
    ``converged = false`` and the solver's message), so a failed run still
    says what happened.
    """
    progress = progress or _quiet
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    summary = {"title": scene["title"]}
    summary.update(ANALYSES[scene["analysis"]["type"]](scene, out, progress))
    summary["wall_time_s"] = time.perf_counter() - t0
    write_json(out / "summary.json", summary)
    return summary
