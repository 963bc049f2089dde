"""Scenes: TOML descriptions of a structure and its analysis, in one schema.

:data:`~shellform.scene_format.SCENE` lists every key: ``load_scene`` reads and
validates a file against it and checks what the schema alone cannot (which
tables suit which geometry and analysis, sizes, node sets); errors name the
key, the value and what is allowed.

A scene takes its geometry from one source: ``[nodes]`` (explicit
coordinates) or ``[geometry]`` of a ``type``: a planform grid meshed by gmsh
(``rectangle``, ``ellipse``, ``disk``) or on a NURBS surface (``bspline``)
for form finding, the Chebyshev-net ``hemisphere`` gridshell, or a ``file``
read by meshio. The analysis (``[analysis] type``) must suit the geometry:

=====================  =============================================
geometry               analyses
=====================  =============================================
``[nodes]``, ``file``  ``static``, ``continuation``, ``dynamics``
planform grids         ``mra``, ``form_and_buckle``
``hemisphere``         ``indentation``
=====================  =============================================

Older MRA scenes (``validation/mra/README.md``) keep working: their
top-level ``[solver]``, ``[start]``, ``[lengths]`` and ``[buckling]`` tables
are read as ``[analysis.relaxation]``, ``[analysis.start_shape]``,
``[analysis.lengths]`` and ``[analysis.buckling]`` (with the rod section of
``[buckling]`` as ``[rods]``), a single ``[supports]`` table as one
``[[supports]]`` entry and ``[loads] gravity`` as ``[gravity] g``.

``build_model`` turns a validated bar/rope scene into a
:class:`~shellform.model.Structure` with its imperfection and a
:class:`~shellform.assembly.System` holding exactly the effects the scene
lists; ``mra_params`` gives the parameters of a form-finding scene for
:func:`shellform.mra.run_mra_case`.
"""

from __future__ import annotations

import importlib.util
import stat
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .assembly import System, member_effects
from .effects import gravity_effect, nodal_load_effects
from .errors import ModelError, SceneError
from .model import Structure
from .scene_format import ANALYSES_OF, BAR_ROPE, BUCKLING, FORM_FINDING, GRID_GROUPS, PLANFORMS, SCENE
from .schema import LIMITS, Table, check_table

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

#: older MRA layout: top-level table -> sub-table of [analysis]
_LEGACY_ANALYSIS = {"solver": "relaxation", "start": "start_shape", "lengths": "lengths", "buckling": "buckling"}
_ROD_KEYS = ("E", "G", "radius", "density", "rest_shape")
_LEGACY_BUCKLING = Table(doc="", keys={**BUCKLING.keys, **{k: SCENE.keys["rods"].keys[k] for k in _ROD_KEYS}})

# which tables and [analysis] keys apply where: name -> (allowed analyses, where it applies, in words)
_TABLE_SCOPE = {
    "members": (BAR_ROPE, "[nodes] and mesh-file scenes"),
    "prescribed": (BAR_ROPE, "[nodes] and mesh-file scenes"),
    "loads": (BAR_ROPE, "[nodes] and mesh-file scenes"),
    "effects": (BAR_ROPE, "[nodes] and mesh-file scenes"),
    "ropes": (FORM_FINDING, "form finding on a planform grid"),
    "rods": (("indentation", "form_and_buckle"), "the hemisphere and form_and_buckle"),
    "masses": (BAR_ROPE + FORM_FINDING, "bar/rope structures and form finding"),
    "supports": (BAR_ROPE + FORM_FINDING, "bar/rope structures and form finding (the hemisphere's rod ends are "
                                          "pinned on its equator)"),
    "gravity": (BAR_ROPE + FORM_FINDING, "bar/rope structures and form finding"),
    "imperfection": (BAR_ROPE + ("indentation",), "bar/rope structures and the hemisphere"),
}
_ROD_SCOPE = {"rest_shape": ("form_and_buckle",), "joints": ("indentation",),
              "joint_stiffness_ratio": ("indentation",)}
_ANALYSIS_SCOPE = {
    "load_factor": BAR_ROPE, "prescribed": BAR_ROPE, "start": BAR_ROPE,
    "merit": ("static",), "max_iterations": ("static",), "rtol": ("static", "continuation"),
    "linear_solver": ("static", "dynamics"),
    "continuation": ("continuation",), "dynamics": ("dynamics",),
    "relaxation": FORM_FINDING, "start_shape": FORM_FINDING, "lengths": ("mra",),
    "buckling": ("form_and_buckle",), "indentation": ("indentation",),
}


#: time steps of a dynamics scene: beyond this a unit is almost certainly off
MAX_TIME_STEPS = 1.0e8
#: size of a scene file: a scene of two million nodes given one by one stays well below it
MAX_SCENE_BYTES = LIMITS["scene_bytes"]
#: nodes of a structure (a planform grid, the hemisphere's rods, a mesh file or [nodes])
MAX_NODES = LIMITS["items"]
#: edge length over radius of a rod: beyond it the start of an indentation is unstable (at 5,000 on the
#: hemisphere of 5 cm the path cannot leave its start, at 50,000 the start itself is unstable)
MAX_SLENDERNESS = 1000


def _source(data: dict) -> str:
    """'nodes', 'planform', 'hemisphere' or 'file' (after [geometry] was validated)."""
    if data.get("nodes") is not None:
        return "nodes"
    kind = data["geometry"]["type"]
    return "planform" if kind in PLANFORMS else kind


def _legacy(data: dict) -> tuple[dict, dict]:
    """Split off the tables of the older MRA layout, validated where they stand."""
    data = dict(data)
    found = {}
    for old, new in _LEGACY_ANALYSIS.items():
        if old not in data:
            continue
        analysis = data.get("analysis")
        if isinstance(analysis, dict) and new in analysis:
            raise SceneError(old, f"given twice: as [{old}] and as [analysis.{new}]; keep one")
        table = _LEGACY_BUCKLING if old == "buckling" else SCENE.keys["analysis"].keys[new]
        given = data.pop(old)
        found[new] = (check_table(old, given, table), set(given))
    if isinstance(data.get("loads"), dict):
        loads = data.pop("loads")
        extra = sorted(set(loads) - {"gravity"})
        if extra:
            raise SceneError(f"loads.{extra[0]}", "a [loads] table takes only 'gravity' (nodal forces are "
                                                  "[[loads]] entries)")
        if "gravity" in loads:
            if "gravity" in data:
                raise SceneError("loads.gravity", "given twice: as [loads] gravity and as [gravity] g; keep one")
            data["gravity"] = {"g": loads["gravity"]}
    return data, found


def parse_scene(data: dict, base_dir=None) -> dict:
    """Validate a scene given as a dictionary; return it with defaults filled.

    Parameters
    ----------
    data : dict
        The scene as read from TOML.
    base_dir : path-like, optional
        Folder that relative file names (``geometry.file``) are relative to;
        default the working directory.
    """
    if not isinstance(data, dict):
        raise SceneError("scene", f"expected a table, got {type(data).__name__}")
    data, legacy = _legacy(data)
    scene = check_table("", data, SCENE)
    if scene["nodes"] is None and scene["geometry"] is None:
        raise SceneError("geometry", "a scene needs its geometry: a [nodes] table or a [geometry] table")
    if scene["nodes"] is not None and scene["geometry"] is not None:
        raise SceneError("geometry", "give either [nodes] or [geometry], not both")
    for new, (table, given) in legacy.items():
        if new == "buckling":
            rods = {k: table.pop(k) for k in _ROD_KEYS}
            given = given & set(_ROD_KEYS)
            clash = given & set((data.get("rods") or {}))
            if clash:
                raise SceneError(f"buckling.{sorted(clash)[0]}", "given twice: in [buckling] and in [rods]")
            scene["rods"] = {**(scene["rods"] or check_table("rods", {}, SCENE.keys["rods"])),
                             **{k: rods[k] for k in given}}
        scene["analysis"][new] = table
    source = _source(scene)
    scene["source"] = source
    scene["single_support"] = isinstance(data.get("supports"), dict)
    _check_scope(data, scene, source, "buckling" in legacy)
    _check_imperfection(scene)
    if source in ("nodes", "file"):
        _check_bar_rope(scene, base_dir)
    elif source == "planform":
        _check_planform(scene)
    else:
        _check_hemisphere(scene)
    return scene


def _check_scope(data: dict, scene: dict, source: str, legacy_buckling: bool) -> None:
    allowed = ANALYSES_OF[source]
    a = scene["analysis"]
    raw = data.get("analysis") or {}
    if a["type"] is None:
        a["type"] = "form_and_buckle" if source == "planform" and ("buckling" in raw or legacy_buckling) \
            else allowed[0]
    elif a["type"] not in allowed:
        what = {"nodes": "a [nodes] scene", "file": "a mesh-file scene", "planform": "a planform grid",
                "hemisphere": "the hemisphere"}[source]
        raise SceneError("analysis.type", f"{a['type']!r} does not apply to {what}; allowed: "
                         + ", ".join(repr(t) for t in allowed))
    t = a["type"]
    for name, (analyses, where) in _TABLE_SCOPE.items():
        if name in data and t not in analyses:
            raise SceneError(name, f"does not apply to analysis {t!r}; it applies to {where}")
    for name, analyses in _ANALYSIS_SCOPE.items():
        if name in raw and t not in analyses:
            raise SceneError(f"analysis.{name}", f"does not apply to analysis {t!r}; it applies to "
                             + ", ".join(repr(x) for x in analyses))
    if t not in BAR_ROPE and "scaled" in (data.get("gravity") or {}):
        raise SceneError("gravity.scaled", f"does not apply to analysis {t!r}")
    rods = data.get("rods") or {}
    legacy = data.get("buckling") if isinstance(data.get("buckling"), dict) else {}
    for name, analyses in _ROD_SCOPE.items():
        if (name in rods or name in legacy) and t not in analyses:
            where = "rods" if name in rods else "buckling"
            raise SceneError(f"{where}.{name}", f"does not apply to analysis {t!r}; it applies to "
                             + ", ".join(repr(x) for x in analyses))
    if "3dm" in scene["output"]["formats"] and importlib.util.find_spec("rhino3dm") is None:
        raise SceneError("output.formats", "'3dm' needs rhino3dm: pip install 'shellform[rhino]'")


def _mesh_of(scene: dict, base_dir):
    from .io.mesh_import import read_mesh

    g = scene["geometry"]
    path = Path(g["file"])
    if not path.is_absolute():
        path = Path(base_dir or ".") / path
    try:
        return read_mesh(path)
    except ModelError as exc:
        raise SceneError("geometry.file", str(exc)) from None


def _check_bar_rope(scene: dict, base_dir) -> None:
    if scene["source"] == "file":
        mesh = _mesh_of(scene, base_dir)
        scene["mesh"] = mesh
        n = len(mesh.points)
    else:
        n = len(scene["nodes"]["coordinates"])
    if not scene["members"]:
        raise SceneError("members", "a bar/rope scene needs at least one [[members]] group")
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
                raise SceneError(_where(scene, i, key), "applies to planform grids (form finding)")
        if scene["source"] == "nodes" and sup["groups"]:
            raise SceneError(_where(scene, i, "groups"), "named node sets come from a planform grid or a mesh file; "
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


def _where(scene: dict, i: int, key: str = "") -> str:
    """The scene key of supports entry ``i`` as the file wrote it ([supports] or [[supports]])."""
    base = "supports" if scene.get("single_support") else f"supports[{i}]"
    return f"{base}.{key}" if key else base


def _need_some(scene: dict, sup: dict, i: int, keys) -> None:
    if all(sup[k] is None or (isinstance(sup[k], list) and not sup[k]) for k in keys):
        raise SceneError(_where(scene, i), "names no nodes: give " + ", ".join(keys[:-1]) + f" or {keys[-1]}")


def _check_planform(scene: dict) -> None:
    if not scene["supports"]:
        raise SceneError("supports", "a hanging net needs suspension points: a [[supports]] entry")
    dofs = {s["dofs"] for s in scene["supports"]}
    if len(dofs) > 1:
        raise SceneError("supports", f"a hanging net holds the same components at every suspension point; got "
                         f"dofs {sorted(dofs)}")
    for i, sup in enumerate(scene["supports"]):
        if sup["z"] is not None:
            raise SceneError(_where(scene, i, "z"), "applies to [nodes] and mesh-file scenes; a planform is flat")
        unknown = sorted(set(sup["groups"] or ()) - set(GRID_GROUPS))
        if unknown:
            raise SceneError(_where(scene, i, "groups"), f"a planform grid has no node set {unknown[0]!r}; its sets: "
                             + ", ".join(repr(g) for g in GRID_GROUPS))
        _need_some(scene, sup, i, ("nodes", "groups", "positions", "frames"))
    _check_grid(scene)
    slack = scene["ropes"]["slack"] if scene["ropes"] else 0.0
    if isinstance(slack, np.ndarray) and slack.shape != (2,):
        raise SceneError("ropes.slack", f"got {len(slack)} values; expected one number or [sc_i, sc_j]")
    if np.any(np.asarray(slack) <= -1.0):
        raise SceneError("ropes.slack", f"got {slack!r}; expected numbers > -1")
    st = scene["analysis"]["start_shape"]
    if st["type"] == "nurbs" and st["depth"] is None and st["control_heights"] is None:
        raise SceneError("analysis.start_shape.depth", "a 'nurbs' start needs a depth or control_heights")


def grid_shape(geometry: dict) -> tuple[int, int]:
    """Nodes along i and j of the structured grid of a validated planform ``[geometry]``."""
    if geometry["type"] in ("ellipse", "disk"):
        return geometry["n"] + 1, geometry["n"] + 1
    return geometry["n_i"] + 1, geometry["n_j"] + 1


def _check_grid(scene: dict) -> None:
    """Sizes of the planform grid and the grid positions, frames and node numbers of its supports."""
    g = scene["geometry"]
    ni, nj = grid_shape(g)
    if ni * nj > MAX_NODES:
        key = "geometry.n" if g["type"] in ("ellipse", "disk") else "geometry.n_i"
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
            position(_where(scene, k, f"positions[{m}]"), pos)
        if sup["nodes"] is not None:
            bad = np.flatnonzero((sup["nodes"] < 0) | (sup["nodes"] >= ni * nj))
            if bad.size:
                raise SceneError(_where(scene, k, f"nodes[{int(bad[0])}]"), f"node {int(sup['nodes'][bad[0]])} is "
                                 f"out of range: the grid has {ni * nj} nodes (0..{ni * nj - 1})")
        for m, frame in enumerate(sup["frames"]):
            where = _where(scene, k, f"frames[{m}]")
            a, b = position(where + ".from", frame["from"]), position(where + ".to", frame["to"])
            if a[0] != b[0] and a[1] != b[1]:
                raise SceneError(where, f"from {list(a)} to {list(b)} is not along one grid line (same i or "
                                 "same j)")


def _check_imperfection(scene: dict) -> None:
    imp = scene["imperfection"]
    if imp is None:
        return
    if imp["type"] == "mode" and imp["amplitude"] == 0.0:
        raise SceneError("imperfection.amplitude", "got 0.0; expected a non-zero number")
    if imp["type"] != "mode" and imp["amplitude"] <= 0.0:
        raise SceneError("imperfection.amplitude", f"got {imp['amplitude']!r}; expected a number > 0 for type "
                         f"{imp['type']!r}")


def _check_hemisphere(scene: dict) -> None:
    g = scene["geometry"]
    n = g["n"]
    if n % 2 == 0 or n < 3:
        raise SceneError("geometry.n", f"got {n}; the hemisphere needs an odd number of rods per direction >= 3")
    from .gridshell.hemisphere import PAPER

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


def _shown(path: Path) -> str:
    """A file name for a message (its last 200 characters)."""
    text = str(path)
    return text if len(text) <= 200 else "..." + text[-197:]


def read_scene_text(path) -> str:
    """The text of a scene file: a regular file of at most ``MAX_SCENE_BYTES``, UTF-8 encoded."""
    path = Path(path)
    where = _shown(path)
    try:
        info = path.stat()
    except (OSError, ValueError) as exc:
        raise SceneError(where, f"cannot read the scene file ({getattr(exc, 'strerror', None) or exc})") from None
    if not stat.S_ISREG(info.st_mode):
        raise SceneError(where, "not a regular file (a directory, device or pipe cannot be a scene)")
    if info.st_size > MAX_SCENE_BYTES:
        raise SceneError(where, f"the file has {info.st_size:,} bytes; a scene may have at most "
                         f"{MAX_SCENE_BYTES:,}")
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise SceneError(where, f"cannot read the scene file ({exc.strerror})") from None
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = raw.count(b"\n", 0, exc.start) + 1
        column = exc.start - (raw.rfind(b"\n", 0, exc.start) + 1) + 1
        raise SceneError(where, f"not UTF-8 text: byte 0x{raw[exc.start]:02x} at line {line}, column {column} "
                         "(save the scene as UTF-8)") from None


def parse_toml(text: str, where: str = "scene") -> dict:
    """A TOML text as a dictionary; errors name the line and what is wrong there."""
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SceneError(where, f"not valid TOML: {exc}") from None
    except RecursionError:  # the parser recurses into nested arrays and inline tables
        raise SceneError(where, "not valid TOML for a scene: arrays or tables nested hundreds of levels deep "
                         "(a scene nests at most four)") from None
    except ValueError:  # an integer of thousands of digits
        raise SceneError(where, "not valid TOML for a scene: an integer of thousands of digits") from None


def load_scene(path) -> dict:
    """Read and validate a TOML scene file (relative file names are relative to its folder)."""
    path = Path(path)
    data = parse_toml(read_scene_text(path), _shown(path))
    scene = parse_scene(data, base_dir=path.parent)
    scene["name"] = scene["name"] or path.stem
    return scene


# -- bar and rope structures ------------------------------------------------------------------


def _model_error_as_scene_error(where: str):
    class _Ctx:
        def __enter__(self):
            return self

        def __exit__(self, typ, exc, tb):
            if typ is not None and issubclass(typ, ModelError):
                raise SceneError(where, str(exc)) from None
            return False

    return _Ctx()


def reference_nodes(scene: dict) -> np.ndarray:
    """Node coordinates of a bar/rope scene as given (before any imperfection)."""
    if scene["source"] == "file":
        return scene["mesh"].points.copy()
    return np.array(scene["nodes"]["coordinates"], dtype=float)


def member_connectivity(scene: dict) -> list[np.ndarray]:
    """End nodes of every member group: as given, or the mesh edges of the listed cells."""
    out = []
    taken = np.zeros(0, dtype=np.int64)
    n = len(reference_nodes(scene))
    for i, m in enumerate(scene["members"]):
        if m["connectivity"] is not None:
            out.append(m["connectivity"])
            continue
        edges = scene["mesh"].edges(m["cells"])
        code = edges[:, 0] * n + edges[:, 1]
        keep = ~np.isin(code, taken)
        if not keep.any():
            held = ", ".join(sorted(scene["mesh"].cells))
            raise SceneError(f"members[{i}].cells", f"selects no edges (the mesh has cells: {held}; edges taken "
                             "by an earlier group are left out)")
        taken = np.concatenate([taken, code[keep]])
        out.append(edges[keep])
    return out


def scene_support_nodes(scene: dict, nodes: np.ndarray) -> list[np.ndarray]:
    """Node numbers of every [[supports]] entry of a bar/rope scene."""
    out = []
    for i, sup in enumerate(scene["supports"]):
        chosen = []
        if sup["nodes"] is not None:
            chosen.append(sup["nodes"])
        for name in sup["groups"] or []:
            mesh = scene["mesh"]
            if name == "boundary":
                chosen.append(mesh.boundary_nodes())
            elif name in mesh.point_sets:
                chosen.append(mesh.point_sets[name])
            else:
                raise SceneError(_where(scene, i, "groups"), f"the mesh has no node set {name!r}; available: "
                                 + ", ".join(["'boundary'"] + [repr(k) for k in sorted(mesh.point_sets)]))
        if sup["z"] is not None:
            at = np.flatnonzero(np.abs(nodes[:, 2] - sup["z"]) <= sup["z_tolerance"])
            if not at.size:
                raise SceneError(_where(scene, i, "z"), f"no node lies at z = {sup['z']} (within "
                                 f"{sup['z_tolerance']} m); the nodes span z = {nodes[:, 2].min():.6g} .. "
                                 f"{nodes[:, 2].max():.6g}")
            chosen.append(at)
        out.append(np.unique(np.concatenate(chosen)))
        if not out[-1].size:
            raise SceneError(_where(scene, i), "selects no nodes")
    return out


def build_structure(scene: dict, nodes: np.ndarray | None = None) -> Structure:
    """The Structure a validated bar/rope scene describes (``nodes`` overrides its coordinates)."""
    nodes = reference_nodes(scene) if nodes is None else nodes
    where = "geometry.file" if scene["source"] == "file" else "nodes.coordinates"
    with _model_error_as_scene_error(where):
        s = Structure(nodes)
    for i, (m, conn) in enumerate(zip(scene["members"], member_connectivity(scene))):
        name = m["name"] or f"{m['kind']}s{i}"
        for k in ("EA", "mass_per_length", "slack", "rest_length"):
            v = m[k]
            if isinstance(v, np.ndarray) and len(v) != len(conn):
                raise SceneError(f"members[{i}].{k}", f"has {len(v)} values for {len(conn)} members")
        with _model_error_as_scene_error(f"members[{i}]"):
            if m["kind"] == "bar":
                s.add_bars(conn, m["EA"], m["mass_per_length"], m["rest_length"], name=name)
            else:
                s.add_ropes(conn, m["EA"], m["slack"], m["mass_per_length"], m["rest_length"], name=name)
    if scene["masses"] is not None and scene["masses"]["node_mass"] > 0:
        s.add_point_mass(np.arange(s.n_nodes), scene["masses"]["node_mass"])
    for i, (sup, at) in enumerate(zip(scene["supports"], scene_support_nodes(scene, np.asarray(nodes)))):
        with _model_error_as_scene_error(_where(scene, i)):
            s.fix(at, sup["dofs"])
    for i, p in enumerate(scene["prescribed"]):
        with _model_error_as_scene_error(f"prescribed[{i}]"):
            s.prescribe(p["nodes"], p["direction"])
    for i, load in enumerate(scene["loads"]):
        with _model_error_as_scene_error(f"loads[{i}]"):
            s.add_load(load["nodes"], load["force"], scaled=load["scaled"])
    if scene["gravity"] is not None:
        s.set_gravity(scene["gravity"]["g"])
    return s


def default_effects(scene: dict) -> list[str]:
    """The effects a scene calls for when it does not list them."""
    kinds = {m["kind"] for m in scene["members"]}
    names = []
    if "bar" in kinds:
        names.append("axial")
    if "rope" in kinds:
        names.append("rope")
    if scene["loads"]:
        names.append("loads")
    if scene["gravity"] is not None:
        names.append("gravity")
    if scene["imperfection"] is not None and scene["imperfection"]["type"] == "forces":
        names.append("imperfection")
    return names


def random_forces(structure: Structure, amplitude: float, seed: int) -> np.ndarray:
    """Random dead forces on the free node translations with total norm ``amplitude``."""
    n = structure.n_nodes
    free = ~structure.constrained_mask[: 3 * n]
    g = np.random.default_rng(seed).normal(size=3 * n) * free
    f = np.zeros(structure.n_dof)
    norm = np.linalg.norm(g)
    if norm > 0:
        f[: 3 * n] = amplitude * g / norm
    return f


def scene_system(scene: dict, structure: Structure) -> System:
    """A System with exactly the effects the scene lists (or calls for)."""
    from .effects.loads import ConstantForce

    include = (scene["effects"] or {}).get("include") or default_effects(scene)
    effects = []
    kind_of = {"axial": "bar", "rope": "rope"}
    for e in member_effects(structure):
        group = structure.group(e.label)
        wanted = [k for k, v in kind_of.items() if v == group.kind][0]
        if wanted in include:
            effects.append(e)
    if "loads" in include:
        effects += nodal_load_effects(structure)
    if "gravity" in include:
        if structure.gravity is None:
            raise SceneError("effects.include", "lists 'gravity' but the scene has no [gravity] table")
        effects.append(gravity_effect(structure, scales_with_load=scene["gravity"]["scaled"]))
    if "imperfection" in include:
        imp = scene["imperfection"]
        if imp is None or imp["type"] != "forces":
            raise SceneError("effects.include", "lists 'imperfection' but the scene has no [imperfection] of type "
                             "'forces'")
        f = random_forces(structure, imp["amplitude"], imp["seed"])
        effects.append(ConstantForce(f, scales_with_load=False, name="imperfection"))
    with _model_error_as_scene_error("supports"):
        return System(structure, effects)


@dataclass
class Model:
    """A bar/rope scene built: its structure, system and imperfection.

    Attributes
    ----------
    structure : Structure
    system : System
    imperfection : dict
        What was applied (JSON-ready; empty without an imperfection).
    """

    structure: Structure
    system: System
    imperfection: dict = field(default_factory=dict)


def _scaled(delta: np.ndarray, amplitude: float, where: str) -> np.ndarray:
    """``delta`` scaled so that its largest node movement is ``|amplitude|`` (sign kept)."""
    size = np.linalg.norm(delta, axis=1).max() if len(delta) else 0.0
    if size == 0:
        raise SceneError(where, "there is no free node to move")
    return delta * (amplitude / size)


def _mode_shape(scene: dict, structure: Structure, system: System) -> tuple[np.ndarray, float]:
    """Lowest eigenmode of the free tangent (translations per node) and its eigenvalue."""
    from .solvers import solve_static
    from .solvers.stability import critical_modes

    imp = scene["imperfection"]
    q = system.state(base=scene_start_state(scene, structure))
    if imp["load_factor"] is not None:
        res = solve_static(system, q0=q, lam=imp["load_factor"], mu=scene["analysis"]["prescribed"])
        if not res.success:
            raise SceneError("imperfection.load_factor", f"no equilibrium at load factor {imp['load_factor']}: "
                             f"{res.message}")
        q = res.q
    values, vectors = critical_modes(system.tangent_free(q), k=1)
    full = np.zeros(structure.n_dof)
    full[system.free] = vectors[:, 0]
    return full[: 3 * structure.n_nodes].reshape(-1, 3), float(values[0])


def build_model(scene: dict) -> Model:
    """Structure and System of a bar/rope scene, with its imperfection applied."""
    structure = build_structure(scene)
    system = scene_system(scene, structure)
    imp = scene["imperfection"]
    if imp is None or imp["type"] == "forces":
        note = {} if imp is None else {"type": "forces", "amplitude_N": imp["amplitude"], "seed": imp["seed"]}
        return Model(structure, system, note)
    nodes = structure.nodes
    free = ~structure.constrained_mask[: 3 * structure.n_nodes].reshape(-1, 3)
    if imp["type"] == "random":
        delta = np.random.default_rng(imp["seed"]).normal(size=nodes.shape) * free
        note = {"type": "random", "seed": imp["seed"]}
    else:
        delta, value = _mode_shape(scene, structure, system)
        note = {"type": "mode", "eigenvalue": value, "load_factor": imp["load_factor"]}
    delta = _scaled(delta, imp["amplitude"], "imperfection.amplitude")
    note.update(amplitude_m=imp["amplitude"], max_node_movement_m=float(np.linalg.norm(delta, axis=1).max()))
    structure = build_structure(scene, nodes + delta)
    return Model(structure, scene_system(scene, structure), note)


def scene_start_state(scene: dict, structure: Structure):
    """The start state of a bar/rope analysis (None: the reference)."""
    start = scene["analysis"]["start"]
    if start is None:
        return None
    q0 = structure.reference_state()
    q0[: 3 * structure.n_nodes] = start.ravel()
    return q0


# -- form finding -----------------------------------------------------------------------


_GEOMETRY_KEYS = {
    "rectangle": ("length_x", "length_y", "n_i", "n_j", "origin"),
    "ellipse": ("a", "b", "n", "center"),
    "disk": ("radius", "n", "center"),
    "bspline": ("control_points", "degree_u", "degree_v", "weights", "n_i", "n_j"),
}


def _plain(v):
    return v.tolist() if isinstance(v, np.ndarray) else v


def mra_params(scene: dict) -> dict:
    """The parameters of :func:`shellform.mra.run_mra_case` for a validated form-finding scene."""
    g = scene["geometry"]
    geometry = {"type": g["type"], **{k: _plain(g[k]) for k in _GEOMETRY_KEYS[g["type"]] if g[k] is not None}}
    supports = {"dofs": scene["supports"][0]["dofs"]}
    for key in ("nodes", "groups", "positions"):
        parts = [_plain(s[key]) for s in scene["supports"] if s[key] is not None]
        if parts:
            supports[key] = [x for p in parts for x in p]
    frames = [{"from": f["from"].tolist(), "to": f["to"].tolist(), "rise": f["rise"]}
              for s in scene["supports"] for f in s["frames"]]
    if frames:
        supports["frames"] = frames
    ropes = dict(scene["ropes"] or check_table("ropes", {}, SCENE.keys["ropes"]))
    ropes["slack"] = _plain(ropes["slack"])
    masses = scene["masses"] or {"node_mass": 0.0}
    gravity = scene["gravity"]["g"] if scene["gravity"] is not None else [0.0, 0.0, -9.81]
    a = scene["analysis"]
    solver = {k: v for k, v in a["relaxation"].items() if k != "checkpoint_interval"}
    start = {k: _plain(v) for k, v in a["start_shape"].items()}
    return {
        "name": scene["name"] or "mra",
        "geometry": geometry,
        "supports": supports,
        "ropes": ropes,
        "masses": dict(masses),
        "loads": {"gravity": _plain(gravity)},
        "solver": solver,
        "start": start,
        "lengths": dict(a["lengths"]),
        "output": {"meshes": scene["output"]["meshes"]},
    }
