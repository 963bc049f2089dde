"""One imperfect structure: its nodes moved, its path traced by arc-length continuation to its first critical point.

The load factor there is the sample's critical load factor: at a limit
point it is the largest load the imperfect structure carries, at a
bifurcation the load at which it first loses stability. A path that ends
(at ``parameter_max``, ``max_displacement`` or ``max_steps``) with no
critical point keeps its stability over the traced range: its critical
load factor is above the largest one reached (``lam_reached``).
"""

from __future__ import annotations

import time

import numpy as np


def imperfect_model(scene: dict, delta: np.ndarray | None):
    """The scene's Structure and System with its stress-free nodes moved by ``delta`` (n_nodes, 3).

    A scene with rods gets its rod network on the moved nodes (copies of
    penalty-joint nodes follow theirs): its imperfect geometry is where the
    rods are stress free, or (``rest_shape = "straight"``) what they are bent into.
    """
    from ..scene.system import scene_system
    from ..scene.build import Model
    from ..scene.structure import build_structure_and_rods, reference_nodes

    nodes = reference_nodes(scene)
    if delta is not None:
        nodes = nodes + delta[: len(nodes)]
    structure, network = build_structure_and_rods(scene, nodes)
    note = {} if delta is None else {"type": "study", "max_node_movement_m": float(np.linalg.norm(delta, axis=1).max())}
    return Model(structure, scene_system(scene, structure, network), note, network)


def trace_to_instability(scene: dict, model, max_step_angle: float, store_states: bool = False):
    """Trace the scene's load-controlled path of ``model`` until its first critical point."""
    from ..analyses.continuation import path_options
    from ..solvers.continuation import trace_path

    options, _, _ = path_options(scene, model.structure, model.system)
    options.update(stop_after_events=1, max_angle_deg=max_step_angle, store_states=store_states)
    return trace_path(model.system, "load", **options)


def critical_record(result) -> dict:
    """What a traced path says about stability: the first critical point, or the range it kept stable over."""
    lam = np.asarray(result.table["lam"], dtype=float) if result.n_points else np.zeros(0)
    record = {"steps": int(result.steps), "message": result.message,
              "lam_reached": float(np.nanmax(lam)) if lam.size and np.isfinite(lam).any() else None}
    if result.events:
        e = result.events[0]
        record.update(status="finished", event=e.kind, lam_cr=float(e.lam), located=bool(e.located))
    elif result.success:
        record.update(status="finished", event="none", lam_cr=None)
    else:
        record.update(status="failed", event="none", lam_cr=None)
    return record


def run_sample(scene: dict, delta: np.ndarray, max_step_angle: float) -> dict:
    """The critical load factor of the scene with its nodes moved by ``delta``; a failure is a record, not raised.

    Module-level so that a pool's worker or a Dask worker finds it by name.
    """
    t0 = time.perf_counter()
    try:
        record = critical_record(trace_to_instability(scene, imperfect_model(scene, delta), max_step_angle))
    except Exception as exc:  # noqa: BLE001 (a worker hands back a row, whatever happened)
        record = {"status": "failed", "event": "none", "lam_cr": None, "message": f"{type(exc).__name__}: {exc}"}
    record["wall_time_s"] = time.perf_counter() - t0
    return record
