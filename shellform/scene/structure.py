"""The Structure of a bar/rope scene: nodes, member groups, rods, supports, loads and its start state."""

from __future__ import annotations

import numpy as np

from ..errors import SceneError
from ..model import Structure
from ..mra.net import add_sliding_support
from .error_keys import scene_error_at, support_key


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
                raise SceneError(support_key(scene, i, "groups"), f"the mesh has no node set {name!r}; available: "
                                 + ", ".join(["'boundary'"] + [repr(k) for k in sorted(mesh.point_sets)]))
        if sup["z"] is not None:
            at = np.flatnonzero(np.abs(nodes[:, 2] - sup["z"]) <= sup["z_tolerance"])
            if not at.size:
                raise SceneError(support_key(scene, i, "z"), f"no node lies at z = {sup['z']} (within "
                                 f"{sup['z_tolerance']} m); the nodes span z = {nodes[:, 2].min():.6g} .. "
                                 f"{nodes[:, 2].max():.6g}")
            chosen.append(at)
        out.append(np.unique(np.concatenate(chosen)))
        if not out[-1].size:
            raise SceneError(support_key(scene, i), "selects no nodes")
    return out


def build_structure(scene: dict, nodes: np.ndarray | None = None) -> Structure:
    """The Structure a validated bar/rope scene describes (``nodes`` overrides its coordinates).

    A scene with rods needs their network too: :func:`build_structure_and_rods`.
    """
    return build_structure_and_rods(scene, nodes)[0]


def build_structure_and_rods(scene: dict, nodes: np.ndarray | None = None):
    """The Structure of a validated bar/rope scene and its RodNetwork (None without ``[rods]``).

    ``nodes`` overrides the scene's node coordinates (the scene's own nodes;
    the copies of penalty joints follow their nodes).
    """
    from .rod_layouts import add_scene_rods, has_rods, rod_layout

    nodes = reference_nodes(scene) if nodes is None else nodes
    layout = rod_layout(scene, nodes) if has_rods(scene) else None
    where = "geometry.file" if scene["source"] == "file" else "nodes.coordinates"
    with scene_error_at(where):
        s = Structure(nodes if layout is None or not len(layout.copies)
                      else np.concatenate([nodes, np.asarray(nodes)[layout.copies]]))
    for i, (m, conn) in enumerate(zip(scene["members"], member_connectivity(scene))):
        name = m["name"] or f"{m['kind']}s{i}"
        for k in ("EA", "mass_per_length", "slack", "rest_length"):
            v = m[k]
            if isinstance(v, np.ndarray) and len(v) != len(conn):
                raise SceneError(f"members[{i}].{k}", f"has {len(v)} values for {len(conn)} members")
        with scene_error_at(f"members[{i}]"):
            if m["kind"] == "bar":
                s.add_bars(conn, m["EA"], m["mass_per_length"], m["rest_length"], name=name)
            else:
                s.add_ropes(conn, m["EA"], m["slack"], m["mass_per_length"], m["rest_length"], name=name)
    if scene["masses"] is not None and scene["masses"]["node_mass"] > 0:
        s.add_point_mass(np.arange(len(nodes)), scene["masses"]["node_mass"])  # not on joint copies
    for i, (sup, at) in enumerate(zip(scene["supports"], scene_support_nodes(scene, np.asarray(nodes)))):
        with scene_error_at(support_key(scene, i)):
            if sup["slide"]:
                add_sliding_support(s, at, sup)
            else:
                s.fix(at, sup["dofs"])
    for i, p in enumerate(scene["prescribed"]):
        with scene_error_at(f"prescribed[{i}]"):
            s.prescribe(p["nodes"], p["direction"])
    for i, load in enumerate(scene["loads"]):
        with scene_error_at(f"loads[{i}]"):
            s.add_load(load["nodes"], load["force"], scaled=load["scaled"])
    if scene["gravity"] is not None:
        s.set_gravity(scene["gravity"]["g"])
    network = add_scene_rods(scene, s, layout) if layout is not None else None
    return s, network


def scene_start_state(scene: dict, structure: Structure):
    """The start state of a bar/rope analysis (None: the reference)."""
    start = scene["analysis"]["start"]
    if start is None:
        return None
    q0 = structure.reference_state()
    q0[: 3 * structure.n_nodes] = start.ravel()
    return q0
