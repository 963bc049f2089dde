"""Static equilibrium of a scene by Newton's method."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .. import scene as scenes
from ..solvers import solve_static
from ..progress import Progress, Status
from .common import build_scene_model, model_sizes, write_final_state


def run_static(scene: dict, out: Path, progress: Progress, resume: bool = False) -> dict:
    model = build_scene_model(scene, progress)
    structure, system = model.structure, model.system
    a = scene["analysis"]
    progress(
        f"static analysis: {structure.n_nodes} nodes, {sum(g.n_members for g in structure.groups)} members, "
        f"{system.n_free} free DOFs, effects: {', '.join(e.name for e in system.effects)}"
    )
    res = solve_static(
        system, q0=scenes.scene_start_state(scene, structure), lam=a["load_factor"], mu=a["prescribed"], rtol=a["rtol"],
        max_iter=a["max_iterations"], merit=a["merit"], linear_solver=a["linear_solver"],
        callback=lambda it, norm: progress(Status(f"  iteration {it:3d}  |r| = {norm:.3e}")),
    )
    progress(res.message)
    files = write_final_state(scene, out, system, res.q, a["load_factor"])
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
        **model_sizes(structure, system),
        "max_displacement": float(np.linalg.norm(x - structure.nodes, axis=1).max()),
        "reaction_sum": R.sum(axis=0),
        "files": files,
    }
    if model.imperfection:
        summary["imperfection"] = model.imperfection
    return summary
