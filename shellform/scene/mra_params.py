"""The parameters of a form-finding scene for :func:`shellform.analyses.form_finding.run_mra_case`."""

from __future__ import annotations

import numpy as np

from .format import SCENE
from .schema import check_table

_GEOMETRY_KEYS = {
    "rectangle": ("length_x", "length_y", "n_i", "n_j", "origin"),
    "ellipse": ("a", "b", "n", "center"),
    "disk": ("radius", "n", "center"),
    "bspline": ("control_points", "degree_u", "degree_v", "weights", "n_i", "n_j"),
    "polygon": ("boundary", "edge_length", "elements"),
    "curves": ("edge_length", "elements"),
    "surface": ("edge_length", "elements"),
    "file": (),
}
#: the keys of a [[supports]] entry that a hanging net reads (besides dofs)
_SUPPORT_KEYS = ("nodes", "groups", "positions", "near", "box", "curve", "tolerance", "z", "z_tolerance")
_CABLE_KEYS = ("name", "nodes", "groups", "near", "box", "curve", "tolerance", "EA", "slack", "mass_per_length")


def _plain(v):
    return v.tolist() if isinstance(v, np.ndarray) else v


def mra_params(scene: dict) -> dict:
    """The parameters of :func:`shellform.analyses.form_finding.run_mra_case` for a validated form-finding scene."""
    from ..mra.net import SLIDE_KEYS

    g = scene["geometry"]
    geometry = {"type": g["type"], **{k: _plain(g[k]) for k in _GEOMETRY_KEYS[g["type"]] if g[k] is not None}}
    if g["type"] == "polygon":
        geometry["holes"] = [_plain(h["points"]) for h in g["holes"]]
    elif g["type"] == "curves":
        geometry["curves"] = [{k: _plain(v) for k, v in c.items()} for c in g["curves"]]
    elif g["type"] in ("surface", "file"):
        geometry["file"] = str(scene["geometry_path"])
    entries = scene["supports"]
    extra = ("near", "box", "curve", "z", "slide")
    if len({s["dofs"] for s in entries}) == 1 and not any(s[k] is not None for s in entries for k in extra):
        # one suspension-point set held alike: the layout of a structured grid's scenes
        supports = {"dofs": entries[0]["dofs"]}
        for key in ("nodes", "groups", "positions"):
            parts = [_plain(s[key]) for s in entries if s[key] is not None]
            if parts:
                supports[key] = [x for p in parts for x in p]
        frames = [{"from": f["from"].tolist(), "to": f["to"].tolist(), "rise": f["rise"]}
                  for s in entries for f in s["frames"]]
        if frames:
            supports["frames"] = frames
    else:
        supports = [{"dofs": s["dofs"], **{k: _plain(s[k]) for k in _SUPPORT_KEYS if s[k] is not None},
                     **({k: _plain(s[k]) for k in SLIDE_KEYS} if s["slide"] else {}),
                     **({"frames": [{"from": f["from"].tolist(), "to": f["to"].tolist(), "rise": f["rise"]}
                                    for f in s["frames"]]} if s["frames"] else {})} for s in entries]
    ropes = dict(scene["ropes"] or check_table("ropes", {}, SCENE.keys["ropes"]))
    ropes["slack"] = _plain(ropes["slack"])
    cables = None
    if scene["cables"]:
        cables = [{k: _plain(c[k]) for k in _CABLE_KEYS if c[k] is not None and not (k == "name" and not c[k])}
                           for c in scene["cables"]]
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
        **({"cables": cables} if cables else {}),
    }
