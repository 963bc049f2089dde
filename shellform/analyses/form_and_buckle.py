"""Form finding continued into a gridshell of rods and traced to its first critical point (see :mod:`.form_finding`)."""

from __future__ import annotations

import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from ..errors import SceneError
from ..io.summary import RunRecord
from ..model import Structure
from ..rods.section import RestShape, RodSection
from .form_finding import ROD_DEFAULTS, Progress, _find_form, grid_lines



def rod_chains(grid) -> list[tuple[np.ndarray, bool]]:
    """Where the laths of a found net run: ``(nodes, closed)`` for every rod.

    A structured grid gives its grid lines; an unstructured quad net (a gmsh
    planform, a mesh file) the straight edge chains of its quads and line
    cells (:func:`~shellform.rods.mesh_lines.edge_chains`). Triangles make no
    straight chains and are refused.
    """
    from ..rods.mesh_lines import edge_chains

    if grid.structured:
        return [(chain, False) for chain in grid_lines(grid)]
    if len(grid.triangles):
        raise SceneError("geometry.elements", "rods follow the straight edge chains of a quad net; this net has "
                         "triangles, whose edges make no straight chains: mesh the planform as quads")
    return [(chain, closed) for chain, closed in edge_chains(grid.n_nodes, grid.quads, grid.lines)
            if len(chain) >= 3 or closed]


def dome_rods(result, section: RodSection, rest: RestShape, plane_z: float | None = None,
              joint_rotation: float = 0.0):
    """The inverted hanging net as a rod gridshell, loaded by its own form-finding weight.

    Every rod edge's first director is the inverted surface's normal
    (:func:`~shellform.rods.mesh_lines.chain_directors`): a rectangular lath
    lies flat on the shell, its depth across it.

    Returns
    -------
    structure : Structure
    network : RodNetwork
    """
    from ..mra.inversion import MIRROR
    from ..rods.mesh_lines import chain_directors, vertex_normals
    from ..rods.network import RodNetwork

    net = result.net
    x = result.positions
    plane = float(x[net.supports, 2].max()) if plane_z is None else plane_z
    xi = x * MIRROR
    xi[:, 2] += 2.0 * plane
    s = Structure(xi)
    s.add_point_mass(np.arange(len(xi)), net.structure.nodal_mass())
    g = net.structure.gravity if net.structure.gravity is not None else np.array([0.0, 0.0, -9.81])
    s.set_gravity(g)  # the shell carries the weight the net hung under, downward
    network = RodNetwork(s)
    normals = vertex_normals(xi, [net.grid.quads])
    for k, (chain, closed) in enumerate(rod_chains(net.grid)):
        director = chain_directors(xi, chain, closed, normals)
        network.add_rod(chain, section, replace(rest, director=director), closed=closed, name=f"rod{k}")
    network.hold_crossing_angles(joint_rotation)
    network.anchor_held_twists()
    s.fix(net.supports)
    # hold the twist of every edge that touches a suspension point: a pinned
    # rod end with free twist could spin about its own axis
    support = np.zeros(s.n_nodes, dtype=bool)
    support[net.supports] = True
    for rod in network.rods:
        b = np.roll(rod.nodes, -1) if rod.closed else rod.nodes[1:]
        touches = support[rod.nodes[: len(b)]] | support[b]
        s.fix_dofs(rod.twist_dofs[touches])
    return s, network


def _section(scene: dict) -> dict:
    """The rods' section (any shape of ``[rods]``; by default the solid circle of ROD_DEFAULTS) and rest shape."""
    from ..scene.rod_layouts import scene_section

    rods = scene["rods"] or {}
    E = rods.get("E") or ROD_DEFAULTS["E"]
    G = rods.get("G") or E / 2.6
    section = scene_section(rods, {**ROD_DEFAULTS, "G": G})
    rest_shape = rods.get("rest_shape") or "straight"
    rest = RestShape(natural_curvature="straight" if rest_shape == "straight" else "rest")
    described = {"section": rods.get("section") or "circle", "E": E, "G": G}
    described.update({k: rods.get(k) or ROD_DEFAULTS.get(k) for k in ("radius", "thickness", "depth", "width")
                      if rods.get(k) is not None or (k == "radius" and described["section"] != "rectangle")})
    joint_rotation = rods.get("joint_rotational_stiffness") or 0.0
    if joint_rotation:
        described["joint_rotational_stiffness"] = joint_rotation
    return {"section": section, "rest": rest, "E": E, "G": G, "described": described, "rest_shape": rest_shape,
            "joint_rotation": joint_rotation}


def run_form_and_buckle(scene: dict, out_dir, progress: Progress | None = None, resume: bool = False,
                        record: RunRecord | None = None) -> dict:
    """Form-find a validated planform scene, then trace the buckling of its rod gridshell.

    The rod section is ``[rods]`` (``E``, ``G``, ``radius``, ``density``,
    ``rest_shape``), the continuation bounds ``[analysis.buckling]``. Writes
    the form-finding files and ``buckling_path.csv``, ``buckling_path.xdmf``,
    ``buckling_curve.png``, ``buckling_path_events.json``, the critical
    points' states and modes and the path's checkpoint. ``record`` (the run's
    summary) is told when each of the two stages, ``form_finding`` and
    ``buckling``, starts and ends, so that a run killed while buckling leaves
    a summary that says so.
    """
    say = progress or (lambda msg: None)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()

    def stage(method, *args, **kwargs):
        if record is not None:
            getattr(record, method)(*args, **kwargs)

    found: dict = {}
    stage("start", "form_finding")
    summary = _find_form(scene, out, say, resume, keep=found)
    summary["analysis"] = "form_and_buckle"
    summary["form_finding_wall_time_s"] = summary.pop("wall_time_s")
    form = found["result"]
    stage("finish", "form_finding", bool(form.converged), summary.get("message"), body=summary)
    if not form.converged:
        # buckling of a form that was not found would answer another question: not run
        return summary
    stage("start", "buckling", body=summary)
    summary, success, message = _buckle(scene, out, form, summary, resume, say)
    summary["wall_time_s"] = time.perf_counter() - t0
    stage("finish", "buckling", success, message, body=summary)
    return summary


def _erected(system, say) -> tuple[np.ndarray | None, str | None]:
    """Laths bent into the found shape: the state after the bending prestress settles, unloaded."""
    from ..solvers import solve_static

    erected = solve_static(system, lam=0.0)
    say(f"erection (prestress relaxed, no load): {erected.message}")
    if not erected.success:
        return None, f"erection failed: {erected.message}"
    system.accept(erected.q)
    return erected.q, None


def _buckle(scene: dict, out: Path, form, summary: dict, resume: bool, say) -> tuple[dict, bool, str]:
    """The buckling stage: the rod gridshell of ``form`` under its own weight, traced to its first critical point."""
    from ..io.table import PathPlot
    from ..rods.network import build_rod_system
    from .continuation import PathFiles, run_continuation_case, write_path_series

    b = scene["analysis"]["buckling"]
    sec = _section(scene)
    structure, network = dome_rods(form, sec["section"], sec["rest"], joint_rotation=sec["joint_rotation"])
    system = build_rod_system(network, gravity_scaled=True)
    q_start = None
    if sec["rest_shape"] == "straight":
        q_start, failure = _erected(system, say)
        if failure is not None:
            return {**summary, "converged": False, "message": failure}, False, failure
    apex = int(np.argmax(structure.nodes[:, 2]))
    say(f"buckling of the inverted shell: {len(network.rods)} rods, {system.n_free} free DOFs; "
        f"self-weight scaled by the load factor up to {b['load_factor_max']}")
    options = dict(parameter_bounds=(0.0, b["load_factor_max"]), max_steps=b["max_steps"], stop_after_events=1,
                   monitors={"apex_w": 3 * apex + 2}, q0=q_start)
    if b["initial_increment"] is not None:
        options["initial_increment"] = b["initial_increment"]
    plot = PathPlot("buckling_curve.png", x="apex_w", xlabel="apex z-displacement [m]",
                    ylabel="load factor on self-weight", title="inverted shell under its own weight",
                    event_x=lambda e: e.q[3 * apex + 2] - structure.nodes[apex, 2])
    path, path_summary = run_continuation_case(
        system, out, "load", PathFiles("buckling_path", plot, b["checkpoint_every"], resume), progress=say,
        **options)
    write_path_series(out / "buckling_path.xdmf", system, path, 0.0)
    first = path.events[0] if path.events else None
    summary["buckling"] = {
        "converged": bool(path.success),
        "message": path.message,
        "steps": int(path.steps),
        "critical_load_factor": float(first.lam) if first else None,
        "critical_kind": first.kind if first else None,
        "max_load_factor_traced": float(np.max(path["lam"])),
        "n_rods": len(network.rods),
        "n_free_dof": int(system.n_free),
        "section": sec["described"],
        "rest_shape": sec["rest_shape"],
    }
    summary["converged"] = bool(summary["converged"] and path.success)
    summary["files"] = summary.get("files", []) + path_summary["files"] + ["buckling_path.xdmf", "buckling_path.h5"]
    # the warnings reach the screen and run.log with the summary's, once
    warnings = list(path_summary.get("warnings", [])) + _buckling_warnings(path, first)
    if warnings:
        summary["warnings"] = summary.get("warnings", []) + warnings
    return summary, bool(path.success), path.message


def _buckling_warnings(path, first) -> list[str]:
    """What a designer must not miss: buckling under less than the found weight, or none found at all."""
    if first is not None and first.lam < 1.0:
        return [f"the shell loses stability under {first.lam:.3g} times its own weight, less than the weight "
                f"it was found for ({first.kind} point at load factor {first.lam:.4g} < 1)"]
    if first is None and path.success:
        return [f"no critical point up to load factor {float(np.max(path['lam'])):.4g}: the buckling load "
                "lies beyond the traced range (raise analysis.buckling.load_factor_max)"]
    return []
