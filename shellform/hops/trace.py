"""The Trace component: a bar or rope structure from lines, traced by arc-length continuation."""

from __future__ import annotations

import json

import numpy as np

from ..errors import ModelError
from .component import Built, Component, line_pairs, nearest_nodes, report
from .protocol import InputError, Param

# -- Trace --------------------------------------------------------------------------------------

_TRACE_INPUTS = (
    Param("Members", "Line", "Members of the structure; their ends closer than Tolerance are one node", "m",
          many=True),
    Param("Kind", "Text", "Member law: bar or rope", default="bar", key="members.kind"),
    Param("EA", "Number", "Axial stiffness of every member", "N", key="members.EA"),
    Param("Supports", "Point", "Supported nodes", "m", many=True, key="supports.nodes"),
    Param("SupportDofs", "Text", "Fixed components of the supports, any of x, y, z: one for all, or one per "
          "support", many=True, default=["xyz"], key="supports.dofs"),
    Param("LoadPoints", "Point", "Loaded nodes", "m", many=True, optional=True, key="loads.nodes"),
    Param("Force", "Vector", "Force on each loaded node, times the load factor", "N", optional=True,
          key="loads.force"),
    Param("PrescribedPoints", "Point", "Nodes moved by the prescribed displacement", "m", many=True, optional=True,
          key="prescribed.nodes"),
    Param("Direction", "Vector", "Their displacement per unit parameter", "m", optional=True,
          key="prescribed.direction"),
    Param("Control", "Text", "Path parameter: load (the load factor) or displacement", default="load",
          key="analysis.continuation.control"),
    Param("ParameterMax", "Number", "Stop when the parameter exceeds this", optional=True,
          key="analysis.continuation.parameter_max"),
    Param("MaxDisplacement", "Number", "Stop when a node moves further than this", "m", optional=True,
          key="analysis.continuation.max_displacement"),
    Param("MaxSteps", "Integer", "Continuation steps before stopping", default=200,
          key="analysis.continuation.max_steps"),
    Param("States", "Number", "Path parameters at which to give the deformed state (the nearest traced state)",
          many=True, optional=True),
    Param("Tolerance", "Number", "Points closer than this are one node", "m", default=1.0e-6),
)


def _trace_scene(v: dict) -> Built:
    from ..io.rhino_import import merge_points

    if not v["Members"]:
        raise InputError("Members", "is required: the lines of the structure")
    tol = v["Tolerance"]
    if isinstance(tol, bool) or not isinstance(tol, (int, float)) or not tol > 0:
        raise InputError("Tolerance", f"got {tol!r}; expected a number > 0")
    ends = np.asarray(v["Members"], dtype=float).reshape(-1, 3)
    nodes, index = merge_points(ends, float(tol))
    pairs = index.reshape(-1, 2)
    if np.any(pairs[:, 0] == pairs[:, 1]):
        k = int(np.flatnonzero(pairs[:, 0] == pairs[:, 1])[0])
        raise InputError("Members", f"item {k} has both ends at one node (shorter than Tolerance)")
    if v["Supports"] is None:
        raise InputError("Supports", "is required: the supported nodes")
    scene = {
        "title": "from Grasshopper",
        "nodes": {"coordinates": nodes.tolist()},
        "members": [{"kind": v["Kind"], "connectivity": pairs.tolist(), "EA": v["EA"]}],
        "supports": _supports(nearest_nodes(nodes, v["Supports"], tol, "Supports"), v["SupportDofs"]),
        "analysis": {"type": "continuation", "continuation": {"control": v["Control"], "max_steps": v["MaxSteps"]}},
    }
    c = scene["analysis"]["continuation"]
    for name, key in (("ParameterMax", "parameter_max"), ("MaxDisplacement", "max_displacement")):
        if v[name] is not None:
            c[key] = v[name]
    if v["LoadPoints"]:
        if v["Force"] is None:
            raise InputError("Force", "is required with LoadPoints")
        scene["loads"] = [{"nodes": nearest_nodes(nodes, v["LoadPoints"], tol, "LoadPoints"), "force": v["Force"]}]
    if v["PrescribedPoints"]:
        if v["Direction"] is None:
            raise InputError("Direction", "is required with PrescribedPoints")
        scene["prescribed"] = [{"nodes": nearest_nodes(nodes, v["PrescribedPoints"], tol, "PrescribedPoints"),
                                "direction": v["Direction"]}]
    keys = {p.key: p.name for p in _TRACE_INPUTS if p.key}
    keys.update({"members": "Members", "supports": "Supports", "loads": "LoadPoints", "prescribed": "PrescribedPoints",
                 "nodes": "Members", "analysis.continuation": "Control"})
    return Built(scene, keys, {"nodes": nodes, "pairs": pairs})


def _supports(nodes: list[int], dofs: list) -> list[dict]:
    """One support entry per distinct set of fixed components."""
    if len(dofs) not in (1, len(nodes)):
        raise InputError("SupportDofs", f"has {len(dofs)} items for {len(nodes)} supports; give one, or one per "
                         "support")
    dofs = dofs * len(nodes) if len(dofs) == 1 else dofs
    entries: dict = {}
    for n, d in zip(nodes, dofs):
        entries.setdefault(d if isinstance(d, str) else json.dumps(d), ([], d))[0].append(n)
    return [{"nodes": ns, "dofs": d} for ns, d in entries.values()]


def _trace_reply(result, v, context) -> dict:
    path = result.table()
    chosen, at = {}, []
    if v["States"]:
        states = result.states()
        if len(states.positions) != len(path["parameter"]):
            raise ModelError(f"the run wrote {len(states.positions)} states for {len(path['parameter'])} points of "
                             "its path; cannot tell the parameter of each state")
        params = np.asarray(path["parameter"], dtype=float)
        for k, want in enumerate(np.asarray(v["States"], dtype=float)):
            j = int(np.argmin(np.abs(params - want)))
            chosen[k] = line_pairs(states.positions[j], context["pairs"])
            at.append(float(params[j]))
    events = result.events
    return {
        "Load": path["load"],
        "Displacement": path["displacement"],
        "Parameter": path["parameter"],
        "Stable": path["n_negative"] == 0,
        "Events": [f"{e['kind']} point at parameter {e['parameter']:.6g}, load {e['load']:.6g}" for e in events],
        "EventLoads": [float(e["load"]) for e in events],
        "DeformedStates": chosen,
        "StateParameters": at,
        "Converged": result.converged,
        "Report": report(result.summary, ("converged", "message", "steps", "events", "wall_time_s")),
    }


TRACE = Component(
    "Trace",
    "Trace the load-displacement path of a bar or rope structure by arc-length continuation, with its critical "
    "points and deformed states.",
    _TRACE_INPUTS,
    (
        Param("Load", "Number", "Generalised load at every point of the path: the load factor under load control, "
              "the reaction to the prescribed motion [N] under displacement control", many=True),
        Param("Displacement", "Number", "Its conjugate displacement", "m", many=True),
        Param("Parameter", "Number", "The path parameter (load factor, or prescribed displacement [m])", many=True),
        Param("Stable", "Boolean", "No negative eigenvalue of the tangent at the point", many=True),
        Param("Events", "Text", "The critical points located (limit, bifurcation)", many=True),
        Param("EventLoads", "Number", "The generalised load at each", many=True),
        Param("DeformedStates", "Line", "The members at the traced state nearest each of States: one branch per "
              "state", "m", many=True),
        Param("StateParameters", "Number", "The path parameter of each state given", many=True),
        Param("Converged", "Boolean", "The path was traced to its end without failure"),
        Param("Report", "Text", "Outcome, steps and events (JSON)"),
    ),
    _trace_scene,
    _trace_reply,
)
