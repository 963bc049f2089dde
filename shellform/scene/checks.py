"""The checks of a scene that the schema alone cannot make, one per kind of geometry.

Sizes, node numbers, node sets and the analysis settings that depend on each
other; errors name the key, the value and what is allowed.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import ModelError, SceneError
from .system import default_effects
from .error_keys import support_key
from .format import GRID_GROUPS, MESHED_PLANFORMS, PLANFORMS

#: planforms meshed as structured grids of a given number of divisions
STRUCTURED_PLANFORMS = tuple(p for p in PLANFORMS if p not in MESHED_PLANFORMS)
from .schema import LIMITS

#: time steps of a dynamics scene: beyond this a unit is almost certainly off
MAX_TIME_STEPS = 1.0e8
#: nodes of a structure (a planform grid, the hemisphere's rods, a mesh file or [nodes])
MAX_NODES = LIMITS["items"]
#: edge length over radius of a rod: beyond it the start of an indentation is unstable (at 5,000 on the
#: hemisphere of 5 cm the path cannot leave its start, at 50,000 the start itself is unstable)
MAX_SLENDERNESS = 1000


def _mesh_of(scene: dict, base_dir):
    """The mesh file of a ``file`` scene, read; its errors name ``geometry.file``."""
    from ..io.mesh_import import read_mesh

    g = scene["geometry"]
    path = Path(g["file"])
    if not path.is_absolute():
        path = Path(base_dir or ".") / path
    rhino = {"layers": g["layers"], "segment_length": g["segment_length"], "tolerance": g["merge_tolerance"]}
    if path.suffix.lower() != ".3dm":
        given = next((k for k in ("layers", "segment_length", "merge_tolerance") if g[k] is not None), None)
        if given is not None:
            raise SceneError(f"geometry.{given}", "applies to Rhino files (.3dm) only")
    try:
        return read_mesh(path, rhino)
    except ModelError as exc:
        raise SceneError("geometry.file", str(exc)) from None


def check_bar_rope(scene: dict, base_dir) -> None:
    """A ``[nodes]`` or mesh-file scene: its members, supports, node numbers and analysis settings."""
    if scene["source"] == "file":
        mesh = _mesh_of(scene, base_dir)
        scene["mesh"] = mesh
        n = len(mesh.points)
    else:
        n = len(scene["nodes"]["coordinates"])
    if not scene["members"] and scene["rods"] is None:
        raise SceneError("members", "a bar/rope scene needs at least one [[members]] group (or [rods])")
    for i, m in enumerate(scene["members"]):
        if m["kind"] == "bar" and np.any(np.asarray(m["slack"]) != 0.0):
            raise SceneError(f"members[{i}].slack", "a slack coefficient applies to ropes only (kind = 'rope')")
        if scene["source"] == "nodes":
            if m["connectivity"] is None:
                raise SceneError(f"members[{i}].connectivity", "this key is required with [nodes]")
            if m["cells"] is not None:
                raise SceneError(f"members[{i}].cells", "selects cells of a mesh file; this scene has [nodes]")
        elif m["connectivity"] is not None and m["cells"] is not None:
            raise SceneError(f"members[{i}].cells", "give connectivity or cells, not both")
    for i, sup in enumerate(scene["supports"]):
        for key in ("positions", "frames"):
            if sup[key] is not None and len(sup[key]):
                raise SceneError(support_key(scene, i, key), "applies to planform grids (form finding)")
        if scene["source"] == "nodes" and sup["groups"]:
            raise SceneError(support_key(scene, i, "groups"), "named node sets come from a planform grid or a mesh file; "
                             "this scene has [nodes]: use nodes or z")
        _need_some(scene, sup, i, ("nodes", "groups", "z"))
    c = scene["analysis"]["continuation"]
    if scene["analysis"]["type"] == "continuation":
        _check_path_bounds(c)
        _check_path_parameter(scene, c)
    d = scene["analysis"]["dynamics"]
    if scene["analysis"]["type"] == "dynamics":
        for key in ("time_step", "duration"):
            if d[key] is None:
                raise SceneError(f"analysis.dynamics.{key}", "this key is required for analysis 'dynamics'")
        if d["duration"] / d["time_step"] > MAX_TIME_STEPS:
            raise SceneError("analysis.dynamics.time_step",
                             f"duration / time_step = {d['duration'] / d['time_step']:.3g} steps; at most "
                             f"{MAX_TIME_STEPS:.0e} are allowed (is a unit off?)")
    for where, mon in (("continuation", c["monitor_node"]), ("dynamics", d["monitor_node"])):
        if mon is not None and mon >= n:
            raise SceneError(f"analysis.{where}.monitor_node",
                             f"node {mon} is out of range (the scene has {n} nodes)")
    start = scene["analysis"]["start"]
    if start is not None and len(start) != n:
        raise SceneError("analysis.start", f"has {len(start)} points; the scene has {n} nodes")


def _check_path_bounds(c: dict) -> None:
    """The path starts at parameter 0 and goes up: its bounds must allow that, and give it a scale."""
    where = "analysis.continuation."
    lo, hi = c["parameter_min"], c["parameter_max"]
    if hi is not None and hi <= 0.0:
        raise SceneError(where + "parameter_max", f"got {hi!r}; expected a number > 0 (the path starts at "
                         "parameter 0 and goes up)")
    if lo is not None and lo > 0.0:
        raise SceneError(where + "parameter_min", f"got {lo!r}; expected a number <= 0 (the path starts at "
                         "parameter 0)")
    if c["initial_increment"] is None and hi is None:
        raise SceneError(where + "parameter_max", "the path needs a scale: give parameter_max (> 0) or "
                         "initial_increment")
    if c["initial_increment"] is not None and c["initial_increment"] == 0.0:
        raise SceneError(where + "initial_increment", "must not be zero")


def _check_path_parameter(scene: dict, c: dict) -> None:
    """The path parameter must act on the structure: a scaled load (load control) or a prescribed motion."""
    include = (scene["effects"] or {}).get("include") or default_effects(scene)
    if c["control"] == "load":
        loads = "loads" in include and any(load["scaled"] for load in scene["loads"])
        weight = "gravity" in include and scene["gravity"] is not None and scene["gravity"]["scaled"]
        if not (loads or weight):
            raise SceneError("analysis.continuation.control", "'load' control needs a load that the load factor "
                             "scales: a [[loads]] entry (scaled = true, the default) or [gravity] scaled = true; "
                             "or control = 'displacement' with [[prescribed]] motion")
    elif not scene["prescribed"]:
        raise SceneError("analysis.continuation.control", "'displacement' control needs a [[prescribed]] motion "
                         "(nodes and a direction) for its parameter")


def _need_some(scene: dict, sup: dict, i: int, keys) -> None:
    """Supports entry ``i`` must give at least one of ``keys``."""
    if all(sup[k] is None or (isinstance(sup[k], list) and not sup[k]) for k in keys):
        raise SceneError(support_key(scene, i), "names no nodes: give " + ", ".join(keys[:-1]) + f" or {keys[-1]}")


def check_planform(scene: dict, base_dir=None) -> None:
    """A hanging net on a planform grid, a gmsh planform or a mesh file: its suspension points, grid, ropes and
    start shape."""
    if not scene["supports"]:
        raise SceneError("supports", "a hanging net needs suspension points: a [[supports]] entry")
    kind = "file" if scene["source"] == "file" else scene["geometry"]["type"]
    structured = kind in STRUCTURED_PLANFORMS
    for i, sup in enumerate(scene["supports"]):
        if not sup["dofs"] or set(sup["dofs"].lower()) - set("xyz"):
            raise SceneError(support_key(scene, i, "dofs"), f"got {sup['dofs']!r}; expected a combination of the "
                             "letters x, y, z (the held components)")
        if sup["z"] is not None and kind not in ("surface", "file"):
            raise SceneError(support_key(scene, i, "z"), "applies to [nodes], mesh-file and surface scenes; a "
                             "planform is flat")
        unknown = sorted(set(sup["groups"] or ()) - set(GRID_GROUPS))
        if structured and unknown:
            raise SceneError(support_key(scene, i, "groups"), f"a planform grid has no node set {unknown[0]!r}; its sets: "
                             + ", ".join(repr(g) for g in GRID_GROUPS))
        for key in ("positions", "frames"):
            if not structured and sup[key] is not None and len(sup[key]):
                raise SceneError(support_key(scene, i, key), f"grid positions need a structured grid (rectangle, "
                                 f"ellipse, disk, bspline); geometry {kind!r} is unstructured: choose nodes by "
                                 "groups, nodes, near, box or curve")
        _need_some(scene, sup, i, ("nodes", "groups", "positions", "frames", "near", "box", "curve", "z"))
    for i, c in enumerate(scene["cables"]):
        if all(c[k] is None for k in ("nodes", "groups", "near", "box", "curve")):
            raise SceneError(f"cables[{i}]", "names no nodes: give nodes, groups, near, box or curve")
    if structured:
        _check_grid(scene)
    else:
        _check_net_geometry(scene, kind, base_dir)
    slack = scene["ropes"]["slack"] if scene["ropes"] else 0.0
    if isinstance(slack, np.ndarray) and slack.shape != (2,):
        raise SceneError("ropes.slack", f"got {len(slack)} values; expected one number or [sc_i, sc_j]")
    if not structured and isinstance(slack, np.ndarray):
        raise SceneError("ropes.slack", "[sc_i, sc_j] needs the two families of grid lines of a structured grid; "
                         f"geometry {kind!r} is unstructured: give one number")
    if np.any(np.asarray(slack) <= -1.0):
        raise SceneError("ropes.slack", f"got {slack!r}; expected numbers > -1")
    st = scene["analysis"]["start_shape"]
    if st["type"] == "nurbs" and st["depth"] is None and st["control_heights"] is None:
        raise SceneError("analysis.start_shape.depth", "a 'nurbs' start needs a depth or control_heights")
    if scene["analysis"]["type"] == "form_and_buckle":
        _check_lath_net(scene, kind)


def _check_lath_net(scene: dict, kind: str) -> None:
    """The laths of form_and_buckle follow straight chains of quad edges: a net of triangles has none."""
    why = ("the laths of form_and_buckle follow the straight edge chains of a quad net, and triangles make no "
           "straight chains")
    if kind == "file" and "triangle" in scene["mesh"].cells:
        raise SceneError("geometry.file", f"{why}; this mesh has triangles: give a quad mesh")
    if kind != "file" and scene["geometry"].get("elements") == "triangles":
        raise SceneError("geometry.elements", f"{why}: mesh the planform as 'quads'")


def _check_net_geometry(scene: dict, kind: str, base_dir) -> None:
    """A gmsh planform's or mesh file's own keys: holes and curves where they apply, files that exist."""
    g = scene["geometry"]
    if kind != "polygon" and g["holes"]:
        raise SceneError("geometry.holes", f"does not apply to type = {kind!r}; it applies to type 'polygon'")
    if kind != "curves" and g["curves"]:
        raise SceneError("geometry.curves", f"does not apply to type = {kind!r}; it applies to type 'curves'")
    if kind == "curves":
        if not g["curves"]:
            raise SceneError("geometry.curves", "type 'curves' needs at least one [[geometry.curves]] entry")
        loops = sorted({c["loop"] for c in g["curves"]})
        if loops != list(range(len(loops))):
            raise SceneError("geometry.curves", f"loops {loops} must be numbered 0 (outer), 1, 2, ... without gaps")
        for k, c in enumerate(g["curves"]):
            n = len(c["control_points"])
            if c["degree"] >= n:
                raise SceneError(f"geometry.curves[{k}].degree", f"got {c['degree']}; expected at most {n - 1} "
                                 f"(the curve has {n} control points)")
            w = c["weights"]
            if isinstance(w, np.ndarray) and len(w) != n:
                raise SceneError(f"geometry.curves[{k}].weights", f"has {len(w)} values for {n} control points")
    if kind == "surface":
        from ..geometry.planforms import SURFACE_FILES

        path = Path(g["file"])
        path = path if path.is_absolute() else Path(base_dir or ".") / path
        if path.suffix.lower() not in SURFACE_FILES:
            raise SceneError("geometry.file", f"got {g['file']!r}; type 'surface' reads "
                             + ", ".join(SURFACE_FILES) + " files")
        if not path.is_file():
            raise SceneError("geometry.file", f"{str(path)!r} does not exist or is not a file")
        scene["geometry_path"] = path.resolve()
    if kind == "file":
        scene["mesh"] = _mesh_of(scene, base_dir)
        path = Path(g["file"])
        scene["geometry_path"] = (path if path.is_absolute() else Path(base_dir or ".") / path).resolve()


def grid_shape(geometry: dict) -> tuple[int, int]:
    """Nodes along i and j of the structured grid of a validated planform ``[geometry]``.

    A gmsh planform of an edge length (polygon, curves) gives the nodes of its bounding box at that spacing,
    an upper estimate; a surface file, unknown before it is meshed, gives (1, 1).
    """
    if geometry["type"] in MESHED_PLANFORMS:
        if geometry["type"] == "surface":
            return 1, 1
        pts = (np.asarray(geometry["boundary"]) if geometry["type"] == "polygon"
               else np.concatenate([c["control_points"] for c in geometry["curves"]]))
        # capped: an edge length of 1e-300 m must reach the size check below, not overflow here
        size = np.minimum(np.ptp(pts, axis=0)[:2] / geometry["edge_length"], 1e12)
        return int(np.ceil(size[0])) + 1, int(np.ceil(size[1])) + 1
    if geometry["type"] in ("ellipse", "disk"):
        return geometry["n"] + 1, geometry["n"] + 1
    return geometry["n_i"] + 1, geometry["n_j"] + 1


def _check_grid(scene: dict) -> None:
    """Sizes of the planform grid and the grid positions, frames and node numbers of its supports."""
    g = scene["geometry"]
    ni, nj = grid_shape(g)
    if ni * nj > MAX_NODES:
        key = ("geometry.n" if g["type"] in ("ellipse", "disk")
               else "geometry.edge_length" if g["type"] in MESHED_PLANFORMS else "geometry.n_i")
        raise SceneError(key, f"the grid would have {ni} x {nj} = {ni * nj:,} nodes; at most {MAX_NODES:,} are "
                         "allowed")
    if g["type"] == "bspline":
        nu, nv = g["control_points"].shape[:2]
        for key, degree, count in (("degree_u", g["degree_u"], nu), ("degree_v", g["degree_v"], nv)):
            if degree >= count:
                raise SceneError(f"geometry.{key}", f"got {degree}; expected at most {count - 1} (the control "
                                 f"points have {count} rows along this direction)")
        if g["weights"] is not None and g["weights"].shape != (nu, nv):
            raise SceneError("geometry.weights", f"has shape {g['weights'].shape[0]} x {g['weights'].shape[1]}; "
                             f"expected {nu} x {nv}, one weight per control point")

    def position(where: str, pos) -> tuple[int, int]:
        i, j = (int(v) for v in pos)
        if not (-ni <= i < ni and -nj <= j < nj):
            raise SceneError(where, f"grid position [{i}, {j}] is out of range: the grid has {ni} x {nj} nodes "
                             f"(i in {-ni}..{ni - 1}, j in {-nj}..{nj - 1}; negative counts from the end)")
        return i % ni, j % nj

    for k, sup in enumerate(scene["supports"]):
        for m, pos in enumerate(sup["positions"] if sup["positions"] is not None else []):
            position(support_key(scene, k, f"positions[{m}]"), pos)
        if sup["nodes"] is not None:
            bad = np.flatnonzero((sup["nodes"] < 0) | (sup["nodes"] >= ni * nj))
            if bad.size:
                raise SceneError(support_key(scene, k, f"nodes[{int(bad[0])}]"), f"node {int(sup['nodes'][bad[0]])} is "
                                 f"out of range: the grid has {ni * nj} nodes (0..{ni * nj - 1})")
        for m, frame in enumerate(sup["frames"]):
            where = support_key(scene, k, f"frames[{m}]")
            a, b = position(where + ".from", frame["from"]), position(where + ".to", frame["to"])
            if a[0] != b[0] and a[1] != b[1]:
                raise SceneError(where, f"from {list(a)} to {list(b)} is not along one grid line (same i or "
                                 "same j)")


def check_imperfection(scene: dict) -> None:
    """The amplitude of an ``[imperfection]``: non-zero for a mode, positive otherwise."""
    imp = scene["imperfection"]
    if imp is None:
        return
    if imp["type"] == "mode" and imp["amplitude"] == 0.0:
        raise SceneError("imperfection.amplitude", "got 0.0; expected a non-zero number")
    if imp["type"] != "mode" and imp["amplitude"] <= 0.0:
        raise SceneError("imperfection.amplitude", f"got {imp['amplitude']!r}; expected a number > 0 for type "
                         f"{imp['type']!r}")


def check_hemisphere(scene: dict) -> None:
    """The hemisphere: rod count, edge length against joint spacing and rod radius, node count."""
    g = scene["geometry"]
    n = g["n"]
    if n % 2 == 0 or n < 3:
        raise SceneError("geometry.n", f"got {n}; the hemisphere needs an odd number of rods per direction >= 3")
    from ..gridshell.hemisphere import PAPER

    radius = g["radius"] if g["radius"] is not None else PAPER["radius"]
    spacing = np.pi * radius / (n + 1)  # between joints along a rod (the Chebyshev net's)
    dl = g["voronoi_length"]
    if dl > spacing:
        raise SceneError("geometry.voronoi_length", f"got {dl!r}; expected at most the joint spacing pi R / (n + 1) "
                         f"= {spacing:.4g} m")
    rods = scene["rods"] or {}
    if rods.get("radius") is not None and 2.0 * rods["radius"] >= spacing:
        raise SceneError("rods.radius", f"got {rods['radius']!r}; expected less than half the joint spacing "
                         f"pi R / (n + 1) = {spacing:.4g} m (thicker rods would overlap their neighbours)")
    rod_radius = rods.get("radius") or PAPER["rod_radius"]
    if rod_radius * MAX_SLENDERNESS < dl:
        # thinner, the rods' bending stiffness vanishes against their stretching and the start is unstable
        key, value = ("rods.radius", rod_radius) if rods.get("radius") else ("geometry.voronoi_length", dl)
        raise SceneError(key, f"got {value!r}; the rods' edges (voronoi_length {dl:.4g} m) may be at most "
                         f"{MAX_SLENDERNESS} times their radius ({rod_radius:.4g} m)")
    nodes = 2 * n * np.pi * radius / dl  # each of the 2 n rods is at most half a great circle long
    if nodes > MAX_NODES:
        raise SceneError("geometry.voronoi_length", f"got {dl!r}: the rods would have about {nodes:,.0f} nodes; at "
                         f"most {MAX_NODES:,} are allowed")
    imp = scene["imperfection"]
    if imp is not None and imp["type"] != "forces":
        raise SceneError("imperfection.type", f"got {imp['type']!r}; the hemisphere takes only 'forces' (random "
                         "dead forces, as in the paper)")


def check_slides(data: dict, scene: dict) -> None:
    """A sliding support names its plane, line or curve, and holds nothing by ``dofs`` besides."""
    raw = data.get("supports")
    raw = [raw] if isinstance(raw, dict) else list(raw or [])
    for i, (sup, given) in enumerate(zip(scene["supports"], raw)):
        kind = sup["slide"]
        for key, applies in (("slide_direction", ("plane", "line")), ("slide_curve", ("curve",))):
            if sup[key] is not None and kind not in applies:
                raise SceneError(support_key(scene, i, key), "applies with slide = "
                                 + " or ".join(repr(a) for a in applies))
        if kind is None:
            continue
        if kind == "curve":
            if sup["slide_curve"] is None and sup["curve"] is None:
                raise SceneError(support_key(scene, i, "slide_curve"), "slide = 'curve' needs the curve: points "
                                 "it passes through, for example [[0.0, 0.0, 0.0], [2.0, 0.0, 1.0], [4.0, 0.0, "
                                 "0.0]] (or the support's own `curve`)")
        elif sup["slide_direction"] is None:
            what = "the plane's normal" if kind == "plane" else "the line's direction"
            raise SceneError(support_key(scene, i, "slide_direction"), f"slide = {kind!r} needs {what}, "
                             "for example [0.0, 0.5, 1.0]")
        elif not np.linalg.norm(sup["slide_direction"]) > 0:
            raise SceneError(support_key(scene, i, "slide_direction"), "got [0, 0, 0]; a direction needs a length")
        if isinstance(given, dict) and "dofs" in given:
            raise SceneError(support_key(scene, i, "dofs"), "a sliding support holds its nodes on the plane, line "
                             "or curve only; give either dofs (axis-aligned) or slide, not both")
