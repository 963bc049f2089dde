"""The form-finding components: FormFind, Lengths and Gridshell on a planform outline or a mesh (Gridshell on
lines: :mod:`.rod_lines`)."""

from __future__ import annotations

import numpy as np

from ..errors import ModelError
from .component import Built, Component, cell_field, line_pairs, nearest_nodes, one_source, report
from .nets import MESH_FILE, NetNodes, check_mesh_groups, mesh_net, support_curves, support_points
from .protocol import InputError, Param

#: samples of a boundary curve that is not a polyline
_BOUNDARY_SAMPLES = 256
#: relative tolerance of the planform recognition (of the boundary's span)
_SHAPE_TOL = 1.0e-6


# -- geometry of the inputs --------------------------------------------------------------------


def _curve_samples(curve) -> np.ndarray:
    from ..io.rhino_import import curve_points

    try:
        return curve_points(curve)
    except ModelError:
        d = curve.Domain
        return np.array([[p.X, p.Y, p.Z] for p in (curve.PointAt(float(t)) for t in
                                                   np.linspace(d.T0, d.T1, _BOUNDARY_SAMPLES + 1))])


def _closed_outline(curve, name: str, edge_length: float) -> np.ndarray:
    """The corners of a closed outline: a polyline's own, or a curve divided into segments of half ``edge_length``."""
    from ..io.rhino_import import curve_points

    if not hasattr(curve, "PointAt"):
        raise InputError(name, f"expected a curve, got a {type(curve).__name__}")
    if not curve.IsClosed:
        raise InputError(name, "is an open curve; an outline is closed")
    pts = curve_points(curve, 0.5 * edge_length, name)
    return pts[:-1] if len(pts) > 1 and np.allclose(pts[0], pts[-1]) else pts


def _polygon_geometry(curve, holes, divisions, edge_length) -> dict:
    """A planform of any outline (with holes), meshed by gmsh at ``edge_length`` (default: the outline's
    perimeter over four times ``divisions``, the quads per side of a square)."""
    if edge_length is None:
        outline = _curve_samples(curve)
        perimeter = float(np.linalg.norm(np.diff(outline, axis=0), axis=1).sum())
        edge_length = perimeter / (4.0 * max(int(divisions), 1))
    boundary = _closed_outline(curve, "Boundary", edge_length)
    loops = [_closed_outline(h, f"Holes[{k}]", edge_length) for k, h in enumerate(holes or [])]
    return {"type": "polygon", "boundary": boundary.tolist(), "holes": [{"points": h.tolist()} for h in loops],
            "edge_length": float(edge_length), "elements": "quads"}


def planform_geometry(curve, divisions, divisions_y, holes=None, edge_length=None) -> dict:
    """The planform keys of a closed boundary curve in a horizontal plane.

    A polyline through the four corners of its bounding box is a
    ``rectangle``; a curve on the ellipse inscribed in its bounding box a
    ``disk`` (equal axes) or an ``ellipse``: structured grids of
    ``divisions``. Any other outline, and any outline with holes or an
    ``edge_length``, is a ``polygon`` meshed by gmsh (quads).
    """
    if not hasattr(curve, "PointAt"):
        raise InputError("Boundary", f"expected a curve, got a {type(curve).__name__}")
    if not curve.IsClosed:
        raise InputError("Boundary", "is an open curve; a planform is a closed outline")
    pts = _curve_samples(curve)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    span = float(np.max(hi - lo))
    tol = _SHAPE_TOL * max(span, 1e-12)
    if hi[2] - lo[2] > tol:
        raise InputError("Boundary", "does not lie in a horizontal plane (z varies along it)")
    if holes or edge_length is not None:
        return _polygon_geometry(curve, holes, divisions, edge_length)
    z = float(lo[2])
    corners = np.array([[lo[0], lo[1]], [hi[0], lo[1]], [hi[0], hi[1]], [lo[0], hi[1]]])
    vertices = np.unique(np.round(pts[:, :2] / tol).astype(np.int64), axis=0)
    is_box = len(vertices) == 4 and all(np.min(np.abs(pts[:, :2] - c).max(axis=1)) <= tol for c in corners)
    if is_box:
        geometry = {"type": "rectangle", "length_x": float(hi[0] - lo[0]), "length_y": float(hi[1] - lo[1]),
                    "origin": [float(lo[0]), float(lo[1]), z], "n_i": divisions,
                    "n_j": divisions if divisions_y is None else divisions_y}
        return geometry
    c = (lo + hi) / 2
    a, b = (hi[0] - lo[0]) / 2, (hi[1] - lo[1]) / 2
    if a > 0 and b > 0:
        off = np.abs(((pts[:, 0] - c[0]) / a) ** 2 + ((pts[:, 1] - c[1]) / b) ** 2 - 1.0).max()
        if off <= 1e-5:
            if divisions_y is not None:
                raise InputError("DivisionsY", "applies to a rectangular boundary only")
            center = [float(c[0]), float(c[1]), z]
            if abs(a - b) <= tol:
                return {"type": "disk", "radius": float(a), "n": divisions, "center": center}
            return {"type": "ellipse", "a": float(a), "b": float(b), "n": divisions, "center": center}
    if divisions_y is not None:
        raise InputError("DivisionsY", "applies to a rectangular boundary only")
    return _polygon_geometry(curve, holes, divisions, edge_length)


# -- the form-finding inputs shared by FormFind, Lengths and Gridshell ---------------------------

_FORM_INPUTS = (
    Param("Boundary", "Curve", "Planform outline in a horizontal plane: a rectangle with sides along x and y, a "
          "circle or an ellipse with axes along x and y (a structured grid), or any other closed curve (meshed "
          "by gmsh as quads). Give this or Mesh", "m", optional=True),
    Param("Mesh", "Mesh", "The net itself instead of an outline: a mesh of quads and/or triangles whose edges are "
          "the ropes (vertices closer than 1e-6 of its size are one node). Give this or Boundary", "m",
          optional=True),
    Param("Holes", "Curve", "Closed outlines of holes in the planform (meshed by gmsh)", "m", many=True,
          optional=True),
    Param("Divisions", "Integer", "Quads per side of the grid (rectangle: along x; circle, ellipse: of the mapped "
          "grid; another outline: its perimeter over four times this is the edge length)", default=10,
          key="geometry.n_i"),
    Param("EdgeLength", "Number", "Target edge length of a gmsh-meshed outline (default: from Divisions)", "m",
          optional=True, key="geometry.edge_length"),
    Param("DivisionsY", "Integer", "Rectangle: quads along y (default: Divisions)", optional=True,
          key="geometry.n_j"),
    Param("Supports", "Text", "Supported node sets of the net, comma separated: of a grid boundary, corners, south, "
          "east, north, west, sw, se, ne, nw; of an outline meshed by gmsh boundary, corners, outer, side_K, hole_H; "
          "of a Mesh boundary, corners; of Lines boundary (where a rod ends); empty for none", default="boundary",
          key="supports.groups"),
    Param("SupportPoints", "Point", "Further supported nodes: the nodes at these points (within a quarter of the "
          "shortest edge)", "m", many=True, optional=True, key="supports.nodes"),
    Param("SupportCurves", "Curve", "Further supported nodes: the nodes on these curves (within a quarter of the "
          "shortest edge)", "m", many=True, optional=True, key="supports.curve"),
    Param("Slack", "Number", "Slack coefficient sc: rest length = (1 + sc) x planform edge length", default=0.0,
          key="ropes.slack"),
    Param("MassPerLength", "Number", "Rope mass, the load of the form", "kg/m", default=1.0,
          key="ropes.mass_per_length"),
    Param("NodeMass", "Number", "Point mass at every node, a further load", "kg", default=0.0,
          key="masses.node_mass"),
    Param("Scheme", "Text", "Relaxation scheme: implicit, rk4 or kinetic", default="implicit",
          key="analysis.relaxation.scheme"),
)
_FORM_KEYS = {p.key: p.name for p in _FORM_INPUTS if p.key}
_FORM_KEYS["geometry.n"] = "Divisions"
_FORM_KEYS["geometry"] = "Boundary"
_FORM_KEYS["geometry.boundary"] = "Boundary"
_FORM_KEYS["geometry.holes"] = "Holes"
_FORM_KEYS["supports"] = "Supports"


def _text_list(value) -> list[str]:
    if not isinstance(value, str):
        return value  # the scene check names what is wrong with it
    return [s.strip() for s in value.split(",") if s.strip()]


def form_scene(v: dict, analysis: str) -> Built:
    """The scene of the form-finding inputs: a net on a planform outline (Boundary) or a given net (Mesh)."""
    source = one_source(v, ("Boundary", "Mesh"), "the planform outline to mesh (Boundary) or the net (Mesh)")
    files, keys = {}, dict(_FORM_KEYS)
    if source == "Mesh":
        geometry, nodes, write = _mesh_geometry(v)
        files[MESH_FILE] = write
        keys.update({"geometry": "Mesh", "geometry.file": "Mesh", "geometry.merge_tolerance": "Mesh"})
    else:
        geometry = planform_geometry(v["Boundary"], v["Divisions"], v["DivisionsY"], v["Holes"], v["EdgeLength"])
        nodes = None
    supports = _supports(v, geometry, nodes)
    scene = {
        "title": "from Grasshopper",
        "geometry": geometry,
        "supports": supports,
        "ropes": {"slack": v["Slack"], "mass_per_length": v["MassPerLength"]},
        "masses": {"node_mass": v["NodeMass"]},
        "analysis": {"type": analysis, "relaxation": {"scheme": v["Scheme"], "checkpoint_interval": 1.0e6}},
    }
    return Built(scene, keys, files=files)


def _mesh_geometry(v: dict):
    """The mesh-file geometry of the Mesh input, the nodes it will have and the writer of its file."""
    for name in ("Holes", "EdgeLength", "DivisionsY"):
        if v[name] is not None:
            raise InputError(name, "applies to a Boundary outline; the Mesh is the net as given")
    net = mesh_net(v["Mesh"])
    check_mesh_groups(_text_list(v["Supports"]))
    return net.geometry, net.nodes, net.write


def _supports(v: dict, geometry: dict, nodes: NetNodes | None) -> list[dict]:
    """The supports entries of the inputs: named sets, nodes at points, nodes on curves."""
    supports = []
    groups = _text_list(v["Supports"])
    if groups:
        supports.append({"groups": groups})
    if (v["SupportPoints"] or v["SupportCurves"]) and nodes is None:
        nodes = _planform_nodes(geometry)
    if v["SupportPoints"]:
        if geometry["type"] == "file":
            supports.append(support_points(nodes, v["SupportPoints"]))
        else:  # grid node numbers, as a scene of the planform gives them
            supports.append({"nodes": nearest_nodes(nodes.nodes, v["SupportPoints"], nodes.reach, "SupportPoints")})
    if v["SupportCurves"]:
        supports += support_curves(nodes, v["SupportCurves"])
    if not supports:
        raise InputError("Supports", "the net needs supports: give node sets, SupportPoints or SupportCurves")
    return supports


def _planform_nodes(geometry: dict) -> NetNodes:
    """The grid of a planform's geometry keys, as the scene will build it: its nodes and shortest edge."""
    from ..errors import SceneError
    from ..mra.case import build_grid
    from ..scene.format import SCENE
    from ..scene.schema import check_table

    try:
        checked = check_table("geometry", geometry, SCENE.keys["geometry"])
    except SceneError as exc:
        raise InputError(_FORM_KEYS.get(exc.key, "Divisions"), str(exc)) from None
    plain = {k: (w.tolist() if isinstance(w, np.ndarray) else w) for k, w in checked.items() if w is not None}
    if geometry["type"] == "polygon":  # as the scene passes it: the holes' points
        plain["holes"] = [h["points"] for h in geometry["holes"]]
    grid = build_grid(plain)
    spacing = float(np.linalg.norm(np.diff(grid.nodes[grid.quads[:, :2]], axis=1), axis=2).min())
    return NetNodes(grid.nodes, spacing)


def _rhino_mesh(points, *faces):
    """A Rhino mesh of the points and the face arrays (quads, triangles)."""
    import rhino3dm

    mesh = rhino3dm.Mesh()
    # from Python lists: a third of the time of numpy rows (4 ms for a thousand quads, not 13)
    add_vertex, add_face = mesh.Vertices.AddPoint3d, mesh.Faces.AddFace
    for x, y, z in np.asarray(points, dtype=float).tolist():
        add_vertex(x, y, z)  # double precision
    for block in faces:
        for f in np.asarray(block, dtype=np.int64).tolist():
            add_face(*f)
    mesh.Normals.ComputeNormals()
    return mesh


# -- FormFind -----------------------------------------------------------------------------------

_FORM_REPORT = ("converged", "message", "iterations", "rise", "n_slack_ropes", "tension_max", "total_weight",
                "reaction_sum", "strain_max", "warnings", "wall_time_s")


def _form_reply(result, v, context) -> dict:
    hang = result.mesh("hanging.vtu")
    lines = hang.cells_dict["line"]
    x = hang.points
    support = hang.point_data["support"] > 0
    out = {
        "HangingNet": line_pairs(x, lines),
        "RopeForces": cell_field(hang, "tension"),
        "Slack": cell_field(hang, "slack") > 0.5,
        "SupportPoints": x[support],
        "Reactions": hang.point_data["reaction"][support],
        "Converged": result.converged,
        "Report": report(result.summary, _FORM_REPORT),
    }
    if "inverted_shell.vtu" in result.files:
        shell = result.mesh("inverted_shell.vtu")
        out["Shell"] = _rhino_mesh(shell.points, *shell.cells_dict.values())
    return out


FORM_FIND = Component(
    "FormFind",
    "Hang a rope net on a planform (MRA dynamic relaxation) and invert it into a shell.",
    _FORM_INPUTS,
    (
        Param("HangingNet", "Line", "The ropes at the hanging equilibrium", "m", many=True),
        Param("Shell", "Mesh", "The inverted shell: the grid's quads at the inverted positions", "m"),
        Param("RopeForces", "Number", "Tension of every rope, in the order of HangingNet", "N", many=True),
        Param("Slack", "Boolean", "Whether each rope is slack", many=True),
        Param("SupportPoints", "Point", "The suspension points", "m", many=True),
        Param("Reactions", "Vector", "Reaction at each suspension point", "N", many=True),
        Param("Converged", "Boolean", "The relaxation came to rest"),
        Param("Report", "Text", "Convergence report: message, iterations, rise, forces (JSON)"),
    ),
    lambda v: form_scene(v, "mra"),
    _form_reply,
)


# -- Lengths ------------------------------------------------------------------------------------

_LENGTH_INPUTS = _FORM_INPUTS + (
    Param("LengthTolerance", "Number", "Relative tolerance of 'the same length'", default=0.01,
          key="analysis.lengths.tolerance"),
    Param("Target", "Number", "Count the ropes within the tolerance of this length", "m", optional=True,
          key="analysis.lengths.target"),
    Param("Control", "Boolean", "Drive the ropes towards Classes lengths", default=False,
          key="analysis.lengths.control"),
    Param("Classes", "Integer", "Length classes of the control", default=3, key="analysis.lengths.n_classes"),
    Param("Rounds", "Integer", "Rounds of the control", default=4, key="analysis.lengths.rounds"),
)


def _lengths_scene(v: dict) -> Built:
    built = form_scene(v, "mra")
    lengths = {"tolerance": v["LengthTolerance"], "control": v["Control"], "n_classes": v["Classes"],
               "rounds": v["Rounds"]}
    if v["Target"] is not None:
        lengths["target"] = v["Target"]
    built.scene["analysis"]["lengths"] = lengths
    built.inputs.update({p.key: p.name for p in _LENGTH_INPUTS if p.key})
    return built


def _lengths_reply(result, v, context) -> dict:
    from ..mra.lengths import tolerance_classes

    s = result.summary
    tol = float(v["LengthTolerance"])
    control = s.get("length_control")
    name = "hanging_length_control.vtu" if control and "hanging_length_control.vtu" in result.files else "hanging.vtu"
    hang = result.mesh(name)
    length = cell_field(hang, "length")
    if control:
        centres = np.asarray(control["centres"], dtype=float)
        label = np.argmin(np.abs(length[:, None] - centres[None, :]), axis=1)
    else:
        label = tolerance_classes(length, tol)
        centres = np.array([length[label == j].mean() for j in range(label.max() + 1)])
    reference = centres[label] if v["Target"] is None else np.full(len(length), float(v["Target"]))
    conforming = np.abs(length - reference) <= tol * reference
    return {
        "HangingNet": line_pairs(hang.points, hang.cells_dict["line"]),
        "RopeLengths": length,
        "LengthClass": label,
        "ClassLengths": centres,
        "Conforming": conforming,
        "ConformingCount": int(conforming.sum()),
        "Converged": result.converged,
        "Report": report(s, ("converged", "message", "rope_lengths", "length_control", "wall_time_s")),
    }


LENGTHS = Component(
    "Lengths",
    "Rope lengths of the found form, their length classes and how many conform (with length control if asked).",
    _LENGTH_INPUTS,
    (
        Param("HangingNet", "Line", "The ropes (after the length control when asked)", "m", many=True),
        Param("RopeLengths", "Number", "Length of every rope at equilibrium", "m", many=True),
        Param("LengthClass", "Integer", "Class of every rope", many=True),
        Param("ClassLengths", "Number", "Length of every class", "m", many=True),
        Param("Conforming", "Boolean", "Rope within the tolerance of its class (of Target when given)", many=True),
        Param("ConformingCount", "Integer", "Conforming ropes"),
        Param("Converged", "Boolean", "The relaxation came to rest"),
        Param("Report", "Text", "Length statistics and control rounds (JSON)"),
    ),
    _lengths_scene,
    _lengths_reply,
)


# -- Gridshell ----------------------------------------------------------------------------------

_GRIDSHELL_INPUTS = _FORM_INPUTS[:2] + (
    Param("Lines", "Curve", "The rods as given instead of a found net: lines, polylines or curves, one rod each, "
          "joined where their points meet (within 1e-6 of the model's size). Give this, Boundary or Mesh", "m",
          many=True, optional=True),
    Param("SegmentLength", "Number", "Lines: curves that are not polylines are divided into segments at most this "
          "long (default: the model's size / 20); lines and polylines keep their vertices", "m", optional=True),
) + _FORM_INPUTS[2:] + (
    Param("Section", "Text", "Shape of the rods' section: circle (Radius), hollow_circle (Radius, Thickness) or "
          "rectangle (Depth across the surface, Width in it); its area, stiffnesses and extreme fibres are computed",
          default="circle", key="rods.section"),
    Param("Radius", "Number", "Radius of a circle, outer radius of a hollow_circle", "m", default=0.02,
          key="rods.radius"),
    Param("Thickness", "Number", "Wall thickness of a hollow_circle", "m", optional=True, key="rods.thickness"),
    Param("Depth", "Number", "Rectangle: the side across the surface (the thickness of a lath lying on it)", "m",
          optional=True, key="rods.depth"),
    Param("Width", "Number", "Rectangle: the side in the surface", "m", optional=True, key="rods.width"),
    Param("E", "Number", "Young's modulus of the rods", "Pa", default=210.0e9, key="rods.E"),
    Param("G", "Number", "Shear modulus of the rods (default E / 2.6)", "Pa", optional=True, key="rods.G"),
    Param("Density", "Number", "Density of the rods (their weight adds to the net's)", "kg/m^3", default=0.0,
          key="rods.density"),
    Param("RestShape", "Text", "Rods straight when unstressed (bent into the form) or stress-free in it: "
          "straight or found", default="straight", key="rods.rest_shape"),
    Param("Joints", "Text", "Lines: rods meeting at a node share it (shared) or each has its own node, tied by a "
          "stiff spring (penalty); default shared", optional=True, key="rods.joints"),
    Param("JointStiffness", "Number", "Rotational spring on the angle between two rods at every crossing (the "
          "scissor stiffness of a tightened joint); default 0: free to turn", "N m/rad", optional=True,
          key="rods.joint_rotational_stiffness"),
    Param("LoadFactorMax", "Number", "Stop tracing at this load factor", default=100.0,
          key="analysis.buckling.load_factor_max"),
    Param("MaxSteps", "Integer", "Continuation steps before stopping", default=60, key="analysis.buckling.max_steps"),
    Param("ModeScale", "Number", "Largest nodal displacement of the drawn buckling mode", "m", default=0.1),
)


def _gridshell_scene(v: dict) -> Built:
    from .rod_lines import lines_scene, section_keys

    source = one_source(v, ("Boundary", "Mesh", "Lines"), "the planform outline to mesh (Boundary), the net "
                        "(Mesh) or the rods (Lines)")
    if source == "Lines":
        return lines_scene(v)
    if v["SegmentLength"] is not None:
        raise InputError("SegmentLength", "applies to Lines")
    built = form_scene(v, "form_and_buckle")
    rods = {**section_keys(v), "E": v["E"], "density": v["Density"], "rest_shape": v["RestShape"],
            "G": v["G"], "joints": v["Joints"], "joint_rotational_stiffness": v["JointStiffness"]}
    built.scene["rods"] = rods
    built.scene["analysis"]["buckling"] = {"load_factor_max": v["LoadFactorMax"], "max_steps": v["MaxSteps"]}
    built.inputs.update({p.key: p.name for p in _GRIDSHELL_INPUTS if p.key})
    return built


def _gridshell_reply(result, v, context) -> dict:
    events = result.events
    out = {"Converged": result.converged,
           "Report": report(result.summary, ("converged", "message", "buckling", "events", "steps", "warnings",
                                             "wall_time_s"))}
    if events:
        crit = result.mesh(events[0]["file"])
        lines = crit.cells_dict["line"]
        x = crit.points
        out["CriticalLoadFactor"] = float(events[0]["lam"])
        out["CriticalKind"] = str(events[0]["kind"])
        out["BucklingMode"] = line_pairs(x + float(v["ModeScale"]) * crit.point_data["mode"], lines)
        fields = {k: cell_field(crit, k) for k in ("axial_force", "bending_moment")}
    else:  # the last traced state
        states = result.states("path.xdmf" if "lines" in context else "buckling_path.xdmf")
        x = states.positions[-1]
        lines = states.cells_nodes
        fields = {k: states.cells[k][-1] if k in states.cells else None for k in ("axial_force", "bending_moment")}
    out["Rods"] = line_pairs(x, lines)
    out["AxialForce"] = fields["axial_force"]
    out["BendingMoment"] = fields["bending_moment"]
    return {k: w for k, w in out.items() if w is not None}


GRIDSHELL = Component(
    "Gridshell",
    "Build a gridshell of elastic rods on the found form and trace its self-weight to the first critical point.",
    _GRIDSHELL_INPUTS,
    (
        Param("CriticalLoadFactor", "Number", "Load factor on the self-weight at the first critical point (empty: "
              "none up to LoadFactorMax)"),
        Param("CriticalKind", "Text", "limit or bifurcation"),
        Param("Rods", "Line", "Rod edges at the critical state (else at the last traced state)", "m", many=True),
        Param("BucklingMode", "Line", "Rod edges moved by the buckling mode times ModeScale", "m", many=True),
        Param("AxialForce", "Number", "Axial force of every rod edge, in the order of Rods", "N", many=True),
        Param("BendingMoment", "Number", "Bending moment of every rod edge", "N m", many=True),
        Param("Converged", "Boolean", "Form finding and tracing finished and converged"),
        Param("Report", "Text", "Buckling summary (JSON)"),
    ),
    _gridshell_scene,
    _gridshell_reply,
)
