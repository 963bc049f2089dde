"""Find a form, then check whether it snaps.

The hanging net of an MRA form finding, mirrored (Hooke), is built as a
gridshell of discrete elastic rods: every grid line becomes one continuous
rod through the shared grid nodes, pinned at the suspension points with the
twist of the edges there held. The rods are either straight when unstressed
(``rest_shape = "straight"``, an elastic gridshell bent into the found form
from straight laths, as the Mannheim Multihalle was; the prestress of bending
is relaxed first) or stress-free in the found shape (``"found"``). Joints
couple positions only, as in the gridshell paper, so rods can roll about
their axes; naturally curved rods of circular section do so under load. Its self-weight
(the load the form was found for) is then scaled by a load factor and the
equilibrium path is traced by arc-length continuation up to the first limit
or bifurcation point: the load factor there is the shell's buckling safety
against its own design load.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from .errors import SceneError
from .model import Structure

BUCKLING_DEFAULTS = {
    "E": 210.0e9,  # Pa
    "G": None,  # default E / 2.6
    "radius": 0.02,  # m, solid circular section
    "density": 0.0,  # kg/m^3 of the rods themselves (the form-finding weight is the load)
    "load_factor_max": 100.0,
    "max_steps": 60,
    "initial_increment": None,
    "rest_shape": "straight",
}


def _merge_buckling(given) -> dict:
    if not isinstance(given, dict):
        raise SceneError("buckling", f"expected a table, got {type(given).__name__}")
    bad = set(given) - set(BUCKLING_DEFAULTS)
    if bad:
        raise SceneError(f"buckling.{sorted(bad)[0]}", f"unknown key; expected one of {sorted(BUCKLING_DEFAULTS)}")
    out = {**BUCKLING_DEFAULTS, **given}
    for key in ("E", "radius", "load_factor_max"):
        v = out[key]
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not np.isfinite(v) or v <= 0:
            raise SceneError(f"buckling.{key}", f"got {v!r}; expected a positive number")
    if out["rest_shape"] not in ("straight", "found"):
        raise SceneError("buckling.rest_shape", f"got {out['rest_shape']!r}; expected 'straight' or 'found'")
    if not isinstance(out["max_steps"], int) or isinstance(out["max_steps"], bool) or out["max_steps"] < 1:
        raise SceneError("buckling.max_steps", f"got {out['max_steps']!r}; expected a positive integer")
    return out


def grid_lines(grid) -> list[np.ndarray]:
    """Node chains of every grid line of a structured quad grid (both families)."""
    index = grid.index()
    lines = []
    for family in (index, index.T):
        for row in family:
            chain = row[row >= 0]
            if len(chain) >= 3:
                lines.append(chain)
    return lines


def dome_rods(result, section: dict, plane_z: float | None = None):
    """The inverted hanging net as a rod gridshell, loaded by its own form-finding weight.

    Returns
    -------
    structure : Structure
    network : RodNetwork
    """
    from .mra.inversion import MIRROR
    from .rods.network import RodNetwork

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
    for k, chain in enumerate(grid_lines(net.grid)):
        network.add_rod(chain, name=f"rod{k}", **section)
    s.fix(net.supports)
    # hold the twist of every edge that touches a suspension point: a pinned
    # rod end with free twist could spin about its own axis
    support = np.zeros(s.n_nodes, dtype=bool)
    support[net.supports] = True
    for rod in network.rods:
        touches = support[rod.nodes[:-1]] | support[rod.nodes[1:]]
        s.fix_dofs(rod.twist_dofs[touches])
    return s, network


def run_form_and_buckle(params: dict, out_dir, progress: Callable[[str], None] | None = None) -> dict:
    """Form-find an MRA case, then trace the buckling of its rod gridshell.

    ``params`` is an MRA case (``validation/mra/README.md``) with an extra
    ``buckling`` table: rod section (``E``, ``G``, ``radius``, ``density``) and
    continuation bounds (``load_factor_max``, ``max_steps``,
    ``initial_increment``).
    """
    from .io import write_series
    from .io.table import plot_curve, write_csv
    from .mra.case import _merge, _solver_options, build_net, start_state, write_meshes
    from .mra.formfind import form_find
    from .mra.inversion import invert
    from .rods.network import build_rod_system, circular_section
    from .solvers import solve_static
    from .solvers.continuation import TABLE_COLUMNS, trace_path

    say = progress or (lambda msg: None)
    out = Path(out_dir)
    params = dict(params)
    b = _merge_buckling(params.pop("buckling", {}))
    t0 = time.perf_counter()
    out.mkdir(parents=True, exist_ok=True)
    p = _merge(params)
    net = build_net(p)
    options = _solver_options(p, progress)
    say(f"form finding: {net.structure.n_nodes} nodes, {len(net.rope_edges)} ropes, "
        f"{len(net.supports)} suspension points")
    q0, _ = start_state(p, net, options)
    form = form_find(net, q0, **options)
    say(form.relaxation.message)
    if not form.converged:
        return {"converged": False, "message": form.relaxation.message, **form.summary()}
    summary = {**form.summary(), "inverted": invert(form).summary()}
    summary["form_finding_wall_time_s"] = summary.pop("wall_time_s")
    summary["files"] = write_meshes(out, form, invert(form))
    section = circular_section(E=b["E"], G=b["G"] or b["E"] / 2.6, radius=b["radius"], density=b["density"])
    section["natural_curvature"] = "straight" if b["rest_shape"] == "straight" else "rest"
    structure, network = dome_rods(form, section)
    system = build_rod_system(network, gravity_scaled=True)
    q_start = None
    if b["rest_shape"] == "straight":
        # laths bent into the found shape: let the bending prestress settle, unloaded
        erected = solve_static(system, lam=0.0)
        say(f"erection (prestress relaxed, no load): {erected.message}")
        if not erected.success:
            return {**summary, "converged": False, "message": f"erection failed: {erected.message}"}
        q_start = erected.q
        system.accept(q_start)
    apex = int(np.argmax(structure.nodes[:, 2]))
    say(f"buckling of the inverted shell: {len(network.rods)} rods, {system.n_free} free DOFs; "
        f"self-weight scaled by the load factor up to {b['load_factor_max']}")

    def report(point):
        say(f"  step {point.step:3d}  load factor {point.lam: .5g}  apex z-displacement {point.monitors['apex_w']: .4g} m"
            f"  negative eigenvalues {point.n_negative}")

    options = dict(parameter_bounds=(0.0, b["load_factor_max"]), max_steps=b["max_steps"], stop_after_events=1,
                   monitors={"apex_w": 3 * apex + 2})
    if b["initial_increment"] is not None:
        options["initial_increment"] = b["initial_increment"]
    path = trace_path(system, control="load", q0=q_start, callback=report, **options)
    say(path.message)
    first = path.events[0] if path.events else None
    columns = list(TABLE_COLUMNS) + ["apex_w"]
    write_csv(out / "buckling_path.csv", path.table, columns)
    write_series(out / "buckling_path.xdmf", system,
                 [(step, q, path.table["lam"][step]) for step, q in zip(path.state_steps, path.states)])
    plot_curve(out / "buckling_curve.png", path["apex_w"], path["lam"], "apex z-displacement [m]",
               "load factor on self-weight", "inverted shell under its own weight",
               marks=[(first.q[3 * apex + 2] - structure.nodes[apex, 2], first.lam, first.kind)] if first else (),
               stable=path["n_negative"] == 0)
    summary["buckling"] = {
        "converged": bool(path.success),
        "message": path.message,
        "steps": int(path.steps),
        "critical_load_factor": float(first.lam) if first else None,
        "critical_kind": first.kind if first else None,
        "max_load_factor_traced": float(np.max(path["lam"])),
        "n_rods": len(network.rods),
        "n_free_dof": int(system.n_free),
        "section": {k: b[k] for k in ("E", "radius")},
        "rest_shape": b["rest_shape"],
    }
    summary["converged"] = bool(summary["converged"] and path.success)
    summary["files"] = summary.get("files", []) + ["buckling_path.csv", "buckling_path.xdmf", "buckling_curve.png"]
    summary["wall_time_s"] = time.perf_counter() - t0
    return summary
