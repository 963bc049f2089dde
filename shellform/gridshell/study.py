"""Whole hemisphere cases as plain functions with JSON-ready results (for validation and scenes)."""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from .hemisphere import (PAPER, HemisphereModel, HemisphereSpec, PrestressResult, build_hemisphere, compare_shapes,
                         prestress_by_paths, prestress_on_net)
from .indentation import indentation_system, trace_indentation
from .indentation_result import IndentationResult

#: the snapping thresholds of the gridshell paper, modes I and II (Huang, Qin, Chen, J. Appl. Mech. 89(1)
#: 011005, 2022, DOI 10.1115/1.4052289)
PUBLISHED = {
    "I": {"snap_dD_over_R": [1.1, 1.7, 1.9], "pattern_sequence": ["U+", "O+", "W", "S", "O-", "U-"]},
    "II": {"snap_dD_over_R": [1.50, 1.75], "pattern_sequence": ["U+", "O+", "W", "O-", "U-"]},
}
TOLERANCE = 0.1
SOURCE = "Numerical Exploration on Snap Buckling of a Pre-Stressed Hemispherical Gridshell, Sec. 3.2, Figs. 6-8"

#: apex displacements of the paper's snapshots (Fig. 4)
SNAPSHOTS = {"I": [0.0, 0.5, 1.25, 1.75, 1.95], "II": [0.0, 0.5, 1.0, 1.6, 1.95]}


def compare_thresholds(computed: Sequence[float], published: Sequence[float], tolerance: float = TOLERANCE):
    """Pair computed and published snapping thresholds in path order.

    Returns one row per published value: ``published``, ``computed`` (None
    when the path has fewer snaps), ``error`` and ``passed``.
    """
    rows = []
    for k, p in enumerate(published):
        c = float(computed[k]) if k < len(computed) else None
        err = None if c is None else c - p
        rows.append({"published": p, "computed": c, "error": err,
                     "passed": bool(err is not None and abs(err) <= tolerance)})
    return rows


@dataclass(frozen=True)
class IndentationCase:
    """One indentation run of a study: the gridshell, its imperfection and how its snaps are passed.

    See :class:`~shellform.gridshell.hemisphere.HemisphereSpec`,
    :func:`~shellform.gridshell.indentation.indentation_system` and
    :func:`~shellform.gridshell.indentation.trace_indentation` for the fields.
    """

    n: int
    mode: str = "I"
    voronoi_length: float = PAPER["voronoi_length"]
    joints: str = "penalty"
    imperfection: float = 1.0e-4
    seed: int = 0
    snap_method: str = "dynamic"


#: the states a picture shows, each with its title
Pictures = Callable[[HemisphereModel, list[tuple[str, np.ndarray]]], None]


def _snapshots(res: IndentationResult, snapshots: Sequence[float]) -> tuple[list, list]:
    """The path points nearest to the requested ``dD / R`` values: titled states and their record."""
    picks, records = [], []
    for s in snapshots:
        i = int(np.argmin(np.abs(res.x - s)))
        picks.append((f"dD/R = {res.x[i]:.2f}: {res.labels[i]}", res.path_states[i]))
        records.append({"requested": s, "dD_over_R": float(res.x[i]), "label": res.labels[i]})
    return picks, records


def _case_summary(case: IndentationCase, model: HemisphereModel, pre: PrestressResult,
                  res: IndentationResult) -> dict:
    """Parameters, sizes, thresholds against the published ones, snaps and the curve of one run."""
    labels = res.labels
    sequence = [lab for i, lab in enumerate(labels) if i == 0 or lab != labels[i - 1]]
    return {
        "n": int(case.n),
        "mode": case.mode,
        "voronoi_length_m": float(case.voronoi_length),
        "joints": case.joints,
        "imperfection": float(case.imperfection),
        "seed": int(case.seed),
        "snap_method": case.snap_method,
        "n_nodes": int(model.structure.n_nodes),
        "n_dof": int(res.n_dof),
        "n_free": int(res.n_free),
        "prestress": {"success": bool(pre.success), "iterations": int(pre.iterations),
                      "apex_height_over_R": float(model.positions(pre.q)[model.apex_nodes, 2].mean() / model.radius)},
        "success": bool(res.success),
        "message": res.message,
        "thresholds": [float(t) for t in res.thresholds],
        "comparison": compare_thresholds(res.thresholds, PUBLISHED[case.mode]["snap_dD_over_R"]),
        "snaps": [s.to_dict() for s in res.snaps],
        "stability_exchanges": [s.to_dict() for s in res.exchanges],
        "max_force": res.max_force,
        "steps": int(res.steps),
        "newton_iterations": int(res.newton_iterations),
        "sequence": sequence,
    }


def indentation_case(
    case: IndentationCase,
    snapshots: Sequence[float] = (),
    pictures: Pictures | None = None,
    progress: Callable[[float, float, int], None] | None = None,
) -> dict:
    """Build, pre-stress (on the net) and indent one gridshell; everything a report needs.

    Parameters
    ----------
    case : IndentationCase
    snapshots : sequence of float
        ``dD / R`` values of configurations to show.
    pictures : callable, optional
        ``pictures(model, [(title, q), ...])`` receives the snapshot
        configurations (to draw them); without it none are picked.
    progress : callable, optional
        See :func:`~shellform.gridshell.indentation.trace_indentation`.

    Returns
    -------
    dict
        Parameters, sizes, timings (``prestress_s``, ``trace_s``,
        ``total_s``), thresholds and their comparison with the published
        values, snaps, maximum force, and the curve (``x = dD/R``,
        ``y = -sum(Fz) R^2/EI``, ``segment``, ``label``).
    """
    t0 = time.perf_counter()
    model = build_hemisphere(HemisphereSpec(case.n, voronoi_length=case.voronoi_length, joints=case.joints))
    pre = prestress_on_net(model)
    t1 = time.perf_counter()
    setup = indentation_system(model, pre, mode=case.mode, imperfection=case.imperfection, seed=case.seed)
    res = trace_indentation(setup, snap_method=case.snap_method, store_states=bool(snapshots), progress=progress)
    t2 = time.perf_counter()
    shown = []
    if snapshots and pictures is not None and res.path_states:
        picks, shown = _snapshots(res, snapshots)
        pictures(model, picks)
    return {
        **_case_summary(case, model, pre, res),
        "snapshots": shown,
        "prestress_s": t1 - t0,
        "trace_s": t2 - t1,
        "total_s": t2 - t0,
        "timings_s": {k: float(v) for k, v in res.timings.items()},
        "curve": {
            "x": [float(v) for v in res.x],
            "y": [float(v) for v in res.y],
            "segment": [int(v) for v in res.segment],
            "label": list(res.labels),
        },
    }


def construction_case(n: int, voronoi_length: float = PAPER["voronoi_length"], n_steps: int = 40) -> dict:
    """Both construction routes for one gridshell and how far apart their shapes are."""
    t0 = time.perf_counter()
    on_net = build_hemisphere(HemisphereSpec(n, voronoi_length=voronoi_length))
    b = prestress_on_net(on_net)
    t1 = time.perf_counter()
    flat = build_hemisphere(HemisphereSpec(n, voronoi_length=voronoi_length, configuration="plane"))
    a = prestress_by_paths(flat, n_steps=n_steps)
    t2 = time.perf_counter()
    out = {
        "n": int(n),
        "voronoi_length_m": float(voronoi_length),
        "n_dof": int(on_net.n_dof),
        "net": {"success": bool(b.success), "steps": int(b.steps), "iterations": int(b.iterations),
                "wall_time_s": t1 - t0},
        "paths": {"success": bool(a.success), "steps": int(a.steps), "iterations": int(a.iterations),
                  "wall_time_s": t2 - t1, "message": a.message},
        "energy_net_J": float(b.system.energy(b.q)),
        "energy_paths_J": float(a.system.energy(a.q)),
    }
    out.update(compare_shapes(on_net, a.q, b.q))
    return out
