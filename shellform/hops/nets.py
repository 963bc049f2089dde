"""The net of the form-finding components given as a mesh, and the supports chosen on a net.

A Rhino mesh given as the net is written to a Rhino file in the request's own
folder and read by the scene as a mesh-file net (``[geometry] type =
"file"``): its vertices, merged within a tolerance relative to its size, are
the nodes and its edges the ropes, exactly as a scene of that file. Supports
are chosen on the nodes the net will have (:class:`NetNodes`): grid nodes of a
planform, vertices of a mesh.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import ModelError
from .component import JOIN_TOLERANCE, nearest_nodes
from .protocol import InputError

#: the file a mesh net is written to (in the request's folder), and the layer it lies on
MESH_FILE = "net.3dm"
MESH_LAYER = "Mesh"
#: the node sets of a mesh net (shellform.geometry.meshnet.MeshNet)
MESH_GROUPS = ("boundary", "corners")
#: a support point or curve takes the nodes within this fraction of the net's shortest edge
SUPPORT_REACH = 0.25
#: a smooth support curve is divided into segments of this fraction of the net's shortest edge
SUPPORT_SEGMENT = 0.25


@dataclass(frozen=True)
class NetNodes:
    """Where the nodes of a net will be, known before the run builds it: to choose and check supports.

    Attributes
    ----------
    nodes : ndarray (n, 3)
        The nodes (of a mesh: its vertices, before merging; merged ones lie within the tolerance).
    spacing : float
        The shortest edge [m].
    """

    nodes: np.ndarray
    spacing: float

    @property
    def reach(self) -> float:
        return SUPPORT_REACH * self.spacing


@dataclass(frozen=True)
class MeshNet:
    """A mesh given as the net: its scene geometry, the writer of its file, its nodes."""

    geometry: dict
    write: object  # (path) -> None
    nodes: NetNodes


def mesh_net(mesh, name: str = "Mesh") -> MeshNet:
    """The mesh-file geometry of a Rhino mesh (quads and/or triangles) given as the net."""
    from ..io.rhino_import import mesh_arrays

    if type(mesh).__name__ != "Mesh":
        raise InputError(name, f"expected a mesh, got a {type(mesh).__name__}")
    points, triangles, quads = mesh_arrays(mesh)
    if not len(triangles) and not len(quads):
        raise InputError(name, "has no faces; a net is a mesh of quads and/or triangles")
    if not np.all(np.isfinite(points)):
        raise InputError(name, "has a vertex with a coordinate that is not a finite number")
    size = float(np.linalg.norm(np.ptp(points, axis=0)))
    if not size > 0:
        raise InputError(name, "has no extent: all its vertices are at one point")
    tolerance = JOIN_TOLERANCE * size
    edges = np.concatenate([_cycle(quads), _cycle(triangles)])
    length = np.linalg.norm(points[edges[:, 0]] - points[edges[:, 1]], axis=1)
    if not np.any(length > tolerance):
        raise InputError(name, "has only faces of zero size")
    geometry = {"type": "file", "file": MESH_FILE, "merge_tolerance": tolerance}
    nodes = NetNodes(points, float(length[length > tolerance].min()))
    return MeshNet(geometry, lambda path: write_mesh_file(mesh, path), nodes)


def _cycle(faces: np.ndarray) -> np.ndarray:
    return np.stack([faces, np.roll(faces, -1, axis=1)], axis=2).reshape(-1, 2)


def write_mesh_file(mesh, path: Path) -> None:
    """A Rhino file (metres) of one mesh on the layer :data:`MESH_LAYER`: what a scene reads as its net."""
    import rhino3dm

    model = rhino3dm.File3dm()
    model.Settings.ModelUnitSystem = rhino3dm.UnitSystem.Meters
    layer = rhino3dm.Layer()
    layer.Name = MESH_LAYER
    attributes = rhino3dm.ObjectAttributes()
    attributes.LayerIndex = model.Layers.Add(layer)
    model.Objects.AddMesh(mesh, attributes)
    if not model.Write(str(path), 7):
        raise ModelError(f"could not write the mesh to {Path(path).name}")


# -- supports on the nodes of a net -------------------------------------------------------------


def check_mesh_groups(groups: list) -> None:
    """A mesh net's node sets are its boundary and corners (a named set of a planform is refused by name)."""
    for g in groups if isinstance(groups, list) else []:
        if g not in MESH_GROUPS:
            raise InputError("Supports", f"a mesh net has no node set {g!r}; its sets: "
                             + ", ".join(repr(s) for s in MESH_GROUPS))


def support_points(net: NetNodes, points, name: str = "SupportPoints") -> dict:
    """A supports entry of the nodes at ``points`` (each within reach of a node, else refused)."""
    nearest_nodes(net.nodes, points, net.reach, name)
    return {"near": np.asarray(points, dtype=float).reshape(-1, 3).tolist()}


def support_curves(net: NetNodes, curves, name: str = "SupportCurves") -> list[dict]:
    """A supports entry per curve: the nodes within reach of it (a curve that passes none is refused)."""
    from ..geometry.selection import nodes_on_polyline

    out = []
    for k, curve in enumerate(curves):
        pts = centreline(curve, SUPPORT_SEGMENT * net.spacing, f"{name}[{k}]")
        if not nodes_on_polyline(net.nodes, pts, net.reach).size:
            raise InputError(name, f"item {k} passes no node of the net (within {net.reach:.3g} m)")
        out.append({"curve": pts.tolist(), "tolerance": net.reach})
    return out


def centreline(curve, segment_length: float, where: str) -> np.ndarray:
    """The points ``(k, 3)`` of a curve: a line's ends, a polyline's vertices, a smooth curve divided into segments
    of at most ``segment_length``."""
    from ..io.rhino_import import curve_points

    name, _, item = where.partition("[")
    if isinstance(curve, list):  # a line item, decoded as its two end points
        ends = np.asarray(curve, dtype=float)
        if ends.shape != (2, 3):
            raise InputError(name, f"item {item.rstrip(']')} is a point or a list, not a line or a curve")
        return ends
    if not hasattr(curve, "PointAt"):
        raise InputError(name, f"item {item.rstrip(']')} is a {type(curve).__name__}, not a curve")
    try:
        return curve_points(curve, segment_length, where)
    except ModelError as exc:
        raise InputError(name, str(exc)) from None
