"""Scenes: TOML descriptions of a structure and its analysis, in one schema.

:data:`~shellform.scene.format.SCENE` lists every key: ``load_scene`` reads and
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
``[nodes]``            ``static``, ``continuation``, ``dynamics``
``file``               those, ``mra`` (any net of quads, triangles, lines)
                       and ``form_and_buckle`` (quads)
planforms              ``mra``, ``form_and_buckle`` (quads)
``hemisphere``         ``indentation``
=====================  =============================================

Older MRA scenes (``validation/mra/README.md``) keep working: their tables
are read where the current layout has them (:mod:`shellform.scene.legacy`),
and a single ``[supports]`` table as one ``[[supports]]`` entry.

``build_model`` turns a validated bar/rope scene into a
:class:`~shellform.model.Structure` with its imperfection and a
:class:`~shellform.assembly.System` holding exactly the effects the scene
lists; ``mra_params`` gives the parameters of a form-finding scene for
:func:`shellform.analyses.form_finding.run_mra_case`.

This package's entry; the parts live in modules of their own: the keys
(``format``) and the machinery that checks and describes them (``schema``),
reading the file (``files``), the older layout (``legacy``), which tables
apply where (``scope``), the checks per geometry (``checks``) and the key a
model error names (``error_keys``); the model built from a scene
(``structure``, ``rod_layouts``, ``system``, ``build``) or the parameters of
a form-finding one (``mra_params``).
"""

from __future__ import annotations

from pathlib import Path

from ..errors import SceneError
from .checks import (
    MAX_NODES,
    MAX_SLENDERNESS,
    MAX_TIME_STEPS,
    check_bar_rope,
    check_hemisphere,
    check_slides,
    check_imperfection,
    check_planform,
    grid_shape,
)
from .system import default_effects, random_forces, scene_system
from .files import MAX_SCENE_BYTES, parse_toml, read_scene_text, shown_path
from .format import FORM_FINDING, PLANFORMS, SCENE
from .legacy import merge_legacy, split_legacy
from .build import Model, build_model
from .mra_params import mra_params
from .scope import check_scope
from .structure import (
    build_structure,
    member_connectivity,
    reference_nodes,
    scene_start_state,
    scene_support_nodes,
)
from .schema import check_table

__all__ = [
    "MAX_NODES",
    "MAX_SCENE_BYTES",
    "MAX_SLENDERNESS",
    "MAX_TIME_STEPS",
    "SCENE",
    "Model",
    "build_model",
    "build_structure",
    "default_effects",
    "grid_shape",
    "load_scene",
    "member_connectivity",
    "mra_params",
    "parse_scene",
    "parse_toml",
    "random_forces",
    "read_scene_text",
    "reference_nodes",
    "scene_start_state",
    "scene_support_nodes",
    "scene_system",
]


def _source(data: dict) -> str:
    """'nodes', 'planform', 'hemisphere' or 'file' (after [geometry] was validated)."""
    if data.get("nodes") is not None:
        return "nodes"
    kind = data["geometry"]["type"]
    return "planform" if kind in PLANFORMS else kind


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
    data, legacy = split_legacy(data)
    scene = check_table("", data, SCENE)
    if scene["nodes"] is None and scene["geometry"] is None:
        raise SceneError("geometry", "a scene needs its geometry: a [nodes] table or a [geometry] table")
    if scene["nodes"] is not None and scene["geometry"] is not None:
        raise SceneError("geometry", "give either [nodes] or [geometry], not both")
    merge_legacy(scene, data, legacy)
    source = _source(scene)
    scene["source"] = source
    scene["single_support"] = isinstance(data.get("supports"), dict)
    check_scope(data, scene, source, "buckling" in legacy)
    check_imperfection(scene)
    check_slides(data, scene)
    if source == "planform" or (source == "file" and scene["analysis"]["type"] in FORM_FINDING):
        check_planform(scene, base_dir)
    elif source in ("nodes", "file"):
        check_bar_rope(scene, base_dir)
    else:
        check_hemisphere(scene)
    return scene


def load_scene(path) -> dict:
    """Read and validate a TOML scene file (relative file names are relative to its folder)."""
    path = Path(path)
    data = parse_toml(read_scene_text(path), shown_path(path))
    scene = parse_scene(data, base_dir=path.parent)
    scene["name"] = scene["name"] or path.stem
    return scene
