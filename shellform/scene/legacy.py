"""The older MRA layout of a scene (``validation/mra/README.md``), read as the current one.

Its top-level ``[solver]``, ``[start]``, ``[lengths]`` and ``[buckling]`` tables
are ``[analysis.relaxation]``, ``[analysis.start_shape]``, ``[analysis.lengths]``
and ``[analysis.buckling]`` (with the rod section of ``[buckling]`` as
``[rods]``); ``[loads] gravity`` is ``[gravity] g``.
"""

from __future__ import annotations

from ..errors import SceneError
from .format import BUCKLING, SCENE
from .schema import Table, check_table

#: older MRA layout: top-level table -> sub-table of [analysis]
_LEGACY_ANALYSIS = {"solver": "relaxation", "start": "start_shape", "lengths": "lengths", "buckling": "buckling"}
_ROD_KEYS = ("E", "G", "radius", "density", "rest_shape")
_LEGACY_BUCKLING = Table(doc="", keys={**BUCKLING.keys, **{k: SCENE.keys["rods"].keys[k] for k in _ROD_KEYS}})


def split_legacy(data: dict) -> tuple[dict, dict]:
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


def merge_legacy(scene: dict, data: dict, legacy: dict) -> None:
    """Put the tables split off by :func:`split_legacy` where the current layout has them."""
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
