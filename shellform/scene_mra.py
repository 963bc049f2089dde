"""The parameters of a form-finding scene for :func:`shellform.analyses.form_finding.run_mra_case`."""

from __future__ import annotations

import numpy as np

from .scene_format import SCENE
from .schema import check_table

_GEOMETRY_KEYS = {
    "rectangle": ("length_x", "length_y", "n_i", "n_j", "origin"),
    "ellipse": ("a", "b", "n", "center"),
    "disk": ("radius", "n", "center"),
    "bspline": ("control_points", "degree_u", "degree_v", "weights", "n_i", "n_j"),
}


def _plain(v):
    return v.tolist() if isinstance(v, np.ndarray) else v


def mra_params(scene: dict) -> dict:
    """The parameters of :func:`shellform.analyses.form_finding.run_mra_case` for a validated form-finding scene."""
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
