"""Time stepping of a scene by implicit Euler, with checkpoints."""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from .. import scene as scenes
from ..assembly import stack_histories, unstack_histories
from ..errors import CheckpointMismatch, SceneError
from ..fingerprint import check_fingerprint, fingerprint_record, model_fingerprint
from ..io import write_series
from ..io.checkpoint import load_checkpoint, save_checkpoint
from ..io.table import plot_curve, write_csv
from ..model import AXES
from ..progress import Progress
from .common import build_scene_model, model_sizes, plot_or_note, write_final_state

DYNAMICS_CHECKPOINT = "dynamics_checkpoint.npz"


def _load_factor_of(scene: dict):
    lam = scene["analysis"]["load_factor"]
    ramp = scene["analysis"]["dynamics"]["ramp_time"]
    if ramp > 0:
        return lambda t: lam * min(t / ramp, 1.0)
    return lambda t: lam


class _History:
    """The time history of a run: the table, the frames of the XDMF series and the checkpoint.

    A checkpoint holds the state, the table and the frames so far, with the
    fingerprint of the model and the settings, so that a resumed run writes the
    files an uninterrupted one would.
    """

    def __init__(self, scene, structure, system, mass, lam, path: Path, fingerprint, settings):
        d = scene["analysis"]["dynamics"]
        self.structure, self.system, self.mass, self.lam = structure, system, mass, lam
        self.path, self.fingerprint, self.settings = path, fingerprint, settings
        self.output_every, self.interval = d["output_every"], d["checkpoint_interval"]
        self.monitor = None
        if d["monitor_node"] is not None:
            self.monitor = (f"u{d['monitor_component']}{d['monitor_node']}",
                            3 * d["monitor_node"] + AXES[d["monitor_component"]])
        self.columns = ["step", "time", "kinetic_energy", "max_displacement"] + ([self.monitor[0]] if self.monitor else [])
        self.table = {c: [] for c in self.columns}
        self.frames = []
        self.step = 0
        self.last_save = time.perf_counter()

    def resume(self, saved, q0):
        """Take up a checkpoint: ``(t, q, v)`` to go on from (a mismatch is refused, naming what differs)."""
        if saved["q"].shape != q0.shape:
            raise CheckpointMismatch(f"{self.path} holds a state of {saved['q'].size} DOFs; this scene has "
                                     f"{q0.size}: delete it or run without --resume")
        check_fingerprint(self.path, json.loads(str(saved["fingerprint"])) if "fingerprint" in saved else None,
                          self.fingerprint, self.settings)
        self.step = int(saved["step"])
        self.table = {c: list(saved[f"history_{c}"]) for c in self.columns}
        histories = unstack_histories(saved, "frame_history", len(saved["frame_t"]), self.path)
        self.frames = [(float(t), q, self.lam(float(t)), h)
                       for t, q, h in zip(saved["frame_t"], saved["frame_q"], histories)]
        # the rod frames the saved state was found with: the motion goes on from them
        frames = unstack_histories(saved, "state_frames", 1, self.path)[0]
        if frames is None and self.system.history() is not None:
            raise CheckpointMismatch(f"{self.path} was written without the rods' reference frames, which a rod "
                                     "state needs to be taken up: delete it or run without --resume")
        self.system.restore_history(frames)
        return float(saved["t"]), saved["q"], saved["v"]

    def save(self, t, q, v):
        save_checkpoint(self.path, t=t, q=q, v=v, step=self.step,
                        fingerprint=fingerprint_record(self.fingerprint, self.settings),
                        frame_t=[f[0] for f in self.frames], frame_q=np.array([f[1] for f in self.frames]),
                        **stack_histories("frame_history", [f[3] for f in self.frames]),
                        **stack_histories("state_frames", [self.system.history()]),
                        **{f"history_{c}": np.asarray(self.table[c]) for c in self.columns})
        self.last_save = time.perf_counter()

    def record(self, t, q, v, count=True) -> bool:
        """One row of the table (and a frame every ``output_every`` steps); a checkpoint when it is due.

        Returns whether a checkpoint was written (the time stepping restarts from that state as a resumed
        run would).
        """
        self.step += count
        x = q[: 3 * self.structure.n_nodes].reshape(-1, 3)
        row = [self.step, t, 0.5 * float(v @ (self.mass * v)),
               float(np.linalg.norm(x - self.structure.nodes, axis=1).max())]
        if self.monitor:
            row.append(float(q[self.monitor[1]] - self.system.q_ref[self.monitor[1]]))
        for c, value in zip(self.columns, row):
            self.table[c].append(value)
        if count and self.step % self.output_every == 0:
            self.frames.append((t, q.copy(), self.lam(t), self.system.history()))
        if time.perf_counter() - self.last_save >= self.interval:
            self.save(t, q, v)
            return True
        return False


def run_dynamics(scene: dict, out: Path, progress: Progress, resume: bool = False) -> dict:
    from ..solvers.implicit_euler import implicit_euler, lumped_mass

    model = build_scene_model(scene, progress)
    structure, system = model.structure, model.system
    a, d = scene["analysis"], scene["analysis"]["dynamics"]
    mass = lumped_mass(structure, model.network)  # rods: their twist inertia on the twist angles
    if not np.any(mass[system.free] > 0):
        raise SceneError("members", "time stepping needs mass at the free nodes: give the members a "
                         "mass_per_length or [masses] node_mass")
    lam = _load_factor_of(scene)
    n = structure.n_nodes
    q0 = system.state(base=scenes.scene_start_state(scene, structure))
    t0, v0 = 0.0, None
    ck_path = out / DYNAMICS_CHECKPOINT
    # what the motion depends on: the model with its masses, and every setting but the end time
    # (a resumed run may go on further) and how often a checkpoint is written
    settings = {k: v for k, v in d.items() if k not in ("duration", "checkpoint_interval")}
    settings.update(load_factor=a["load_factor"], prescribed=a["prescribed"], linear_solver=a["linear_solver"],
                    start=scenes.scene_start_state(scene, structure))
    hist = _History(scene, structure, system, mass, lam, ck_path, model_fingerprint(system, mass=mass), settings)
    saved = load_checkpoint(ck_path) if resume else None
    if saved is not None:
        t0, q0, v0 = hist.resume(saved, q0)
        progress(f"resuming the time stepping at t = {t0:.6g} s (step {hist.step}) from {ck_path.name}")
    else:
        if resume:
            progress(f"no checkpoint in {out}: starting at t = 0")
        hist.frames = [(0.0, q0.copy(), lam(0.0), system.history())]
        hist.record(t0, q0, np.zeros_like(q0), count=False)
    progress(f"time stepping: {n} nodes, {system.n_free} free DOFs, h = {d['time_step']} s up to "
             f"t = {d['duration']} s, damping {d['damping']} 1/s")
    if t0 < d["duration"] * (1 - 1e-12):
        res = implicit_euler(system, d["time_step"], d["duration"], q0=q0, v0=v0, mass=mass, damping=d["damping"],
                             lam=lam, mu=a["prescribed"], t0=t0, linear_solver=a["linear_solver"], callback=hist.record)
        q_end, v_end, t_end = res.q, res.v, res.t
        success, message = res.success, res.message
        steps, rejected = res.steps, res.rejected_steps
        newton = int(sum(res.newton_iterations))
    else:
        q_end, v_end, t_end = q0, v0, t0
        success, message, steps, rejected, newton = True, f"reached t = {t0:.6g} s (from the checkpoint)", 0, 0, 0
    progress(message)
    hist.save(t_end, q_end, v_end if v_end is not None else np.zeros_like(q_end))
    if hist.frames[-1][0] != t_end:
        hist.frames.append((t_end, q_end.copy(), lam(t_end), system.history()))
    files, notes = _write_history(scene, out, system, hist, q_end, lam(t_end))
    r = system.residual(q_end, lam(t_end))
    summary = {
        "analysis": "dynamics",
        "converged": bool(success),
        "message": message,
        "time": float(t_end),
        "steps": int(hist.step),
        "steps_this_run": int(steps),
        "rejected_steps": int(rejected),
        "newton_iterations": newton,
        "frames": len(hist.frames),
        "kinetic_energy": float(hist.table["kinetic_energy"][-1]),
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


def _write_history(scene, out: Path, system, hist: _History, q_end, lam_end) -> tuple[list[str], list[str]]:
    """The table, the XDMF series, the plot and the final state; the files written and notes on plots."""
    units = {"step": "-", "time": "s", "kinetic_energy": "J", "max_displacement": "m"}
    if hist.monitor:
        units[hist.monitor[0]] = "m"
    files = [write_csv(out / "dynamics.csv", hist.table, hist.columns, units=units).name]
    write_series(out / "dynamics.xdmf", system, hist.frames, time_name="time [s]")
    files += ["dynamics.xdmf", "dynamics.h5"]
    y = hist.monitor[0] if hist.monitor else "max_displacement"
    notes: list[str] = []
    plot_or_note(out / "dynamics.png", lambda: plot_curve(out / "dynamics.png", hist.table["time"], hist.table[y],
                                                          "time [s]", f"{y} [m]", scene["title"]), files, notes)
    files += write_final_state(scene, out, system, q_end, lam_end, [f for f in scene["output"]["formats"] if f != "xdmf"])
    files.append(DYNAMICS_CHECKPOINT)
    return files, notes
