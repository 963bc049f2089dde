"""Time stepping of a scene by implicit Euler, with checkpoints."""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from .. import scene as scenes
from ..errors import SceneError
from ..io import write_series
from ..io.checkpoint import (CheckpointMismatch, check_fingerprint, fingerprint_record, load_checkpoint,
                            model_fingerprint, save_checkpoint)
from ..io.table import plot_curve, write_csv
from ..model import AXES
from .common import Progress, build_scene_model, plot_or_note, model_sizes, write_final_state


DYNAMICS_CHECKPOINT = "dynamics_checkpoint.npz"


def _load_factor_of(scene: dict):
    lam = scene["analysis"]["load_factor"]
    ramp = scene["analysis"]["dynamics"]["ramp_time"]
    if ramp > 0:
        return lambda t: lam * min(t / ramp, 1.0)
    return lambda t: lam


def run_dynamics(scene: dict, out: Path, progress: Progress, resume: bool = False) -> dict:
    from ..solvers.implicit_euler import implicit_euler, lumped_mass

    model = build_scene_model(scene, progress)
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
    q0 = system.state(base=scenes.scene_start_state(scene, structure))
    t0, v0, step = 0.0, None, 0
    frames = [(0.0, q0.copy(), lam(0.0))]
    ck_path = out / DYNAMICS_CHECKPOINT
    # what the motion depends on: the model with its masses, and every setting but the end time
    # (a resumed run may go on further) and how often a checkpoint is written
    fingerprint = model_fingerprint(system, mass=mass)
    settings = {k: v for k, v in d.items() if k not in ("duration", "checkpoint_interval")}
    settings.update(load_factor=a["load_factor"], prescribed=a["prescribed"], linear_solver=a["linear_solver"],
                    start=scenes.scene_start_state(scene, structure))
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
    plot_or_note(out / "dynamics.png", lambda: plot_curve(out / "dynamics.png", history["time"], history[y], "time [s]",
                                                   f"{y} [m]", scene["title"]), files, notes)
    files += write_final_state(scene, out, system, q_end, lam(t_end),
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
        **model_sizes(structure, system),
        "files": files,
    }
    if notes:
        summary["warnings"] = notes
    if model.imperfection:
        summary["imperfection"] = model.imperfection
    return summary
