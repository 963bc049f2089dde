"""Scenes: TOML descriptions of a structure and its analysis.

``load_scene`` reads and validates a file against :data:`SCENE` (errors name
the key, the value and what is allowed); ``build_structure`` turns the
validated scene into a :class:`~shellform.model.Structure`; ``build_effects``
creates exactly the effects the scene lists.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from .assembly import System, member_effects
from .effects import gravity_effect, nodal_load_effects
from .errors import ModelError, SceneError
from .model import Structure
from .schema import Key, Table, check_table

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

EFFECTS = ("axial", "rope", "loads", "gravity")

SCENE = Table(
    doc="A scene file.",
    keys={
        "title": Key("str", "Free text shown in the summary.", default=""),
        "nodes": Table(
            optional=False,
            doc="Node coordinates of the reference configuration.",
            keys={"coordinates": Key("points", "Reference coordinates, one [x, y, z] per node.", unit="m")},
        ),
        "members": Table(
            array=True,
            doc="Groups of two-node members sharing one law.",
            keys={
                "name": Key("str", "Group name (unique).", default=""),
                "kind": Key("str", "Member law.", choices=("bar", "rope")),
                "connectivity": Key("pairs", "End nodes of each member."),
                "EA": Key("float_or_list", "Axial stiffness, one value or one per member.", unit="N",
                          minimum=0.0, exclusive_minimum=True),
                "mass_per_length": Key("float_or_list", "Linear density for self-weight.", default=0.0,
                                       unit="kg/m", minimum=0.0),
                "slack": Key("float_or_list", "Rope slack coefficient sc: rest length = (1 + sc) x reference "
                             "length. Ropes only.", default=0.0, minimum=-1.0, exclusive_minimum=True),
                "rest_length": Key("float_or_list", "Unstressed length; overrides the reference length and "
                                   "slack.", default=None, unit="m", minimum=0.0, exclusive_minimum=True),
            },
        ),
        "supports": Table(
            array=True,
            doc="Fixed translational components of nodes.",
            keys={
                "nodes": Key("index_list", "Supported nodes."),
                "dofs": Key("str", "Fixed components, any of the letters x, y, z.", default="xyz"),
            },
        ),
        "prescribed": Table(
            array=True,
            doc="Prescribed motion: displacement = parameter x direction.",
            keys={
                "nodes": Key("index_list", "Driven nodes."),
                "direction": Key("vec3", "Displacement per unit parameter.", unit="m"),
            },
        ),
        "loads": Table(
            array=True,
            doc="Nodal forces.",
            keys={
                "nodes": Key("index_list", "Loaded nodes."),
                "force": Key("vec3", "Force on each listed node.", unit="N"),
                "scaled": Key("bool", "Multiplied by the load factor (else a dead load).", default=True),
            },
        ),
        "gravity": Table(
            doc="Self-weight of member and point masses.",
            keys={
                "g": Key("vec3", "Gravitational acceleration.", default=[0.0, 0.0, -9.81], unit="m/s^2"),
                "scaled": Key("bool", "Multiplied by the load factor (else a dead load).", default=False),
            },
        ),
        "effects": Table(
            doc="The physical effects to simulate; nothing else is evaluated.",
            keys={
                "include": Key("str_list", "Effects in the system. Default: those the scene's members and "
                               "loads call for.", default=None, choices=EFFECTS),
            },
        ),
        "analysis": Table(
            fill_defaults=True,
            doc="What to compute.",
            keys={
                "type": Key("str", "Analysis to run: one static solve, or a path traced by arc-length "
                            "continuation (settings in [analysis.continuation]).", default="static",
                            choices=("static", "continuation")),
                "load_factor": Key("float", "Factor on the scaled loads.", default=1.0),
                "prescribed": Key("float", "Prescribed-displacement parameter.", default=0.0),
                "start": Key("points", "Starting coordinates (default: the reference).", default=None, unit="m"),
                "merit": Key("str", "Line-search merit: energy finds stable equilibria, residual any.",
                             default="energy", choices=("energy", "residual")),
                "max_iterations": Key("int", "Newton iterations before giving up.", default=100, minimum=1),
                "rtol": Key("float", "Residual tolerance relative to the load/reaction norm.", default=1e-10,
                            minimum=0.0, exclusive_minimum=True),
                "linear_solver": Key("str", "Linear solver.", default="direct", choices=("direct", "amg", "auto")),
                "continuation": Table(
                    fill_defaults=True,
                    doc="Arc-length continuation (used when type = 'continuation'). The path starts from "
                        "equilibrium at parameter 0 (the other parameter at its [analysis] value).",
                    keys={
                        "control": Key("str", "Path parameter: the load factor or the prescribed-displacement "
                                       "parameter.", default="load", choices=("load", "displacement")),
                        "max_steps": Key("int", "Accepted steps before stopping.", default=200, minimum=1),
                        "parameter_min": Key("float", "Stop when the parameter falls below this.", default=None),
                        "parameter_max": Key("float", "Stop when the parameter exceeds this.", default=None),
                        "initial_increment": Key("float", "First parameter increment (default: 1/20 of the "
                                                 "distance to the bound).", default=None),
                        "max_displacement": Key("float", "Stop when a free DOF moves further than this.",
                                                default=None, unit="m", minimum=0.0, exclusive_minimum=True),
                        "constraint": Key("str", "Arc-length constraint.", default="spherical",
                                          choices=("spherical", "cylindrical")),
                        "stability": Key("bool", "Count negative eigenvalues of the tangent at every point.",
                                         default=True),
                        "on_bifurcation": Key("str", "At a bifurcation: stay on the primary branch, follow the "
                                              "secondary one, or stop.", default="continue",
                                              choices=("continue", "switch", "stop")),
                        "branch_side": Key("int", "Which half of the secondary branch (+1 or -1).", default=1),
                        "monitor_node": Key("int", "Node whose displacement is the curve's abscissa (default: "
                                            "the most loaded or driven DOF).", default=None, minimum=0),
                        "monitor_component": Key("str", "Component of monitor_node.", default="z",
                                                 choices=("x", "y", "z")),
                        "checkpoint_every": Key("int", "Write a checkpoint every this many steps.", default=10,
                                                minimum=1),
                    },
                ),
            },
        ),
        "output": Table(
            fill_defaults=True,
            doc="What to write.",
            keys={
                "formats": Key("str_list", "Formats of the final state (3dm: Rhino, needs the rhino extra).",
                               default=["vtu", "xdmf"], choices=("vtu", "vtk", "xdmf", "3dm")),
            },
        ),
    },
)


def is_form_finding(data: dict) -> bool:
    """A form-finding (MRA) scene describes a planform ``[geometry]`` instead of ``[nodes]``."""
    analysis = data.get("analysis")
    return (isinstance(analysis, dict) and analysis.get("type") == "mra") or (
        "geometry" in data and "nodes" not in data)


def parse_form_finding(data: dict) -> dict:
    """Validate an MRA form-finding scene (keys in ``validation/mra/README.md``)."""
    from .mra.case import _merge

    analysis = data.get("analysis", {})
    if not isinstance(analysis, dict) or set(analysis) - {"type"}:
        raise SceneError("analysis", "a form-finding scene takes only analysis.type = 'mra'; its solver "
                         "settings go in [solver]")
    from .formbuckle import _merge_buckling

    params = {k: v for k, v in data.items() if k not in ("analysis", "buckling")}
    merged = _merge(params)
    buckling = _merge_buckling(data["buckling"]) if "buckling" in data else None
    title = data.get("title") or data.get("description") or merged["name"]
    if not isinstance(title, str):
        raise SceneError("title", f"got {title!r}; expected a string")
    if buckling is not None:
        return {"title": title, "analysis": {"type": "form_and_buckle"}, "mra": {**params, "buckling": data["buckling"]}}
    return {"title": title, "analysis": {"type": "mra"}, "mra": params}


def parse_scene(data: dict) -> dict:
    """Validate a scene given as a dictionary; return it with defaults filled."""
    if is_form_finding(data):
        return parse_form_finding(data)
    scene = check_table("", data, SCENE)
    n = len(scene["nodes"]["coordinates"])
    for i, m in enumerate(scene["members"]):
        if m["kind"] == "bar" and m["slack"] != 0.0:
            raise SceneError(f"members[{i}].slack", "a slack coefficient applies to ropes only (kind = 'rope')")
        for k in ("EA", "mass_per_length", "slack", "rest_length"):
            v = m[k]
            if isinstance(v, np.ndarray) and len(v) != len(m["connectivity"]):
                raise SceneError(f"members[{i}].{k}", f"has {len(v)} values for {len(m['connectivity'])} members")
    c = scene["analysis"]["continuation"]
    if scene["analysis"]["type"] == "continuation":
        if c["initial_increment"] is None and c["parameter_min"] is None and c["parameter_max"] is None:
            raise SceneError("analysis.continuation.parameter_max",
                             "the path needs a scale: give parameter_max, parameter_min or initial_increment")
        if c["initial_increment"] is not None and c["initial_increment"] == 0.0:
            raise SceneError("analysis.continuation.initial_increment", "must not be zero")
    mon = c["monitor_node"]
    if mon is not None and mon >= n:
        raise SceneError("analysis.continuation.monitor_node", f"node {mon} is out of range (the scene has {n} nodes)")
    start = scene["analysis"]["start"]
    if start is not None and len(start) != n:
        raise SceneError("analysis.start", f"has {len(start)} points; the scene has {n} nodes")
    return scene


def load_scene(path) -> dict:
    """Read and validate a TOML scene file."""
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as exc:
        raise SceneError(str(path), f"cannot read the scene file ({exc.strerror})") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SceneError(str(path), f"not valid TOML: {exc}") from None
    return parse_scene(data)


def _model_error_as_scene_error(where: str):
    class _Ctx:
        def __enter__(self):
            return self

        def __exit__(self, typ, exc, tb):
            if typ is not None and issubclass(typ, ModelError):
                raise SceneError(where, str(exc)) from None
            return False

    return _Ctx()


def build_structure(scene: dict) -> Structure:
    """The Structure a validated scene describes."""
    with _model_error_as_scene_error("nodes.coordinates"):
        s = Structure(scene["nodes"]["coordinates"])
    for i, m in enumerate(scene["members"]):
        name = m["name"] or f"{m['kind']}s{i}"
        with _model_error_as_scene_error(f"members[{i}]"):
            if m["kind"] == "bar":
                s.add_bars(m["connectivity"], m["EA"], m["mass_per_length"], m["rest_length"], name=name)
            else:
                s.add_ropes(m["connectivity"], m["EA"], m["slack"], m["mass_per_length"], m["rest_length"], name=name)
    for i, sup in enumerate(scene["supports"]):
        with _model_error_as_scene_error(f"supports[{i}]"):
            s.fix(sup["nodes"], sup["dofs"])
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
    return names


def build_system(scene: dict, structure: Structure) -> System:
    """A System with exactly the effects the scene lists (or calls for)."""
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
    with _model_error_as_scene_error("supports"):
        return System(structure, effects)
