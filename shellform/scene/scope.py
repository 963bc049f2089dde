"""Which tables and ``[analysis]`` keys apply to which analysis."""

from __future__ import annotations

import importlib.util

from ..errors import SceneError
from .format import ANALYSES_OF, BAR_ROPE, FORM_FINDING

# which tables and [analysis] keys apply where: name -> (allowed analyses, where it applies, in words)
_TABLE_SCOPE = {
    "members": (BAR_ROPE, "[nodes] and mesh-file scenes"),
    "prescribed": (BAR_ROPE, "[nodes] and mesh-file scenes"),
    "loads": (BAR_ROPE, "[nodes] and mesh-file scenes"),
    "effects": (BAR_ROPE, "[nodes] and mesh-file scenes"),
    "ropes": (FORM_FINDING, "form finding"),
    "cables": (FORM_FINDING, "form finding"),
    "rods": (BAR_ROPE + ("indentation", "form_and_buckle"), "rod scenes, the hemisphere and form_and_buckle"),
    "masses": (BAR_ROPE + FORM_FINDING, "bar/rope structures and form finding"),
    "supports": (BAR_ROPE + FORM_FINDING, "bar/rope structures and form finding (the hemisphere's rod ends are "
                                          "pinned on its equator)"),
    "gravity": (BAR_ROPE + FORM_FINDING, "bar/rope structures and form finding"),
    "imperfection": (BAR_ROPE + ("indentation",), "bar/rope structures and the hemisphere"),
}
_ROD_SCOPE = {"rest_shape": ("form_and_buckle",) + BAR_ROPE, "joints": ("indentation",) + BAR_ROPE,
              "joint_rotational_stiffness": ("form_and_buckle",) + BAR_ROPE,
              "joint_stiffness_ratio": ("indentation",) + BAR_ROPE,
              **{k: ("form_and_buckle",) + BAR_ROPE for k in ("section", "thickness", "depth", "width")},
              **{k: BAR_ROPE for k in ("layout", "lines", "orientation", "support_rotation")}}
_ANALYSIS_SCOPE = {
    "load_factor": BAR_ROPE, "prescribed": BAR_ROPE, "start": BAR_ROPE,
    "merit": ("static",), "max_iterations": ("static",), "rtol": ("static", "continuation"),
    "linear_solver": ("static", "dynamics"),
    "continuation": ("continuation",), "dynamics": ("dynamics",),
    "relaxation": FORM_FINDING, "start_shape": FORM_FINDING, "lengths": ("mra",),
    "buckling": ("form_and_buckle",), "indentation": ("indentation",),
}


def check_scope(data: dict, scene: dict, source: str, legacy_buckling: bool) -> None:
    """Fill in the analysis type and refuse tables and keys that do not apply to it."""
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
