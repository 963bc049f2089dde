"""Rhino ``.3dm`` files and rhino3dm geometry as structural geometry.

A ``.3dm`` file is read into the same :class:`~shellform.io.mesh_import.ImportedMesh`
that a meshio file gives, so a scene's ``[geometry] type = "file"`` takes it
like any mesh file:

* curves (lines, polylines, and other curves divided into segments of at most
  ``segment_length``) become chains of line cells: rod centrelines, edge
  arches, bars and ropes;
* meshes become triangle and quad cells: nets;
* points become nodes of the named set of their layer (supports, loaded
  nodes); a point must lie on a node of a curve or mesh;
* every layer is a named node set (its full path, ``parent::child``, and its
  own name when that is unique), and so is the value of an object's user text
  ``shellform:set``.

Coordinates are converted from the file's model units to metres, and curve
ends, mesh vertices and points closer than the merge tolerance (default the
file's absolute tolerance) become one node. Surfaces, breps, SubDs, blocks
and annotations are not structural geometry: a file that holds them on a read
layer is refused, naming the layer and the object.

The helpers (:func:`curve_points`, :func:`mesh_arrays`, :func:`merge_points`)
turn rhino3dm objects into arrays; the Hops server decodes its inputs with
them.
"""

from __future__ import annotations

import stat
from pathlib import Path

import numpy as np

from ..errors import ModelError
from ..geometry.selection import coincident_groups
from .mesh_import import MAX_COORDINATE, MAX_MESH_BYTES, MAX_POINTS, ImportedMesh, unique_edges

#: metres per model unit
UNIT_SCALE = {
    "Meters": 1.0, "Millimeters": 1.0e-3, "Centimeters": 1.0e-2, "Decimeters": 0.1, "Kilometers": 1.0e3,
    "Microns": 1.0e-6, "Inches": 0.0254, "Feet": 0.3048, "Yards": 0.9144, "Miles": 1609.344,
}
#: user text key whose value names a node set an object belongs to
SET_KEY = "shellform:set"
#: samples per span of a curve before it is divided into equal segments
_SAMPLES_PER_SPAN = 64


def rhino():
    """The rhino3dm module (optional extra ``rhino``)."""
    try:
        import rhino3dm
    except ImportError:  # pragma: no cover
        raise ImportError("Rhino files need rhino3dm: pip install 'shellform[rhino]'") from None
    return rhino3dm


def unit_scale(unit_system) -> float:
    """Metres per unit of a rhino3dm ``UnitSystem`` (``None``: metres assumed)."""
    name = str(unit_system).rsplit(".", 1)[-1]
    if name in ("None", "Unset"):
        return 1.0
    if name not in UNIT_SCALE:
        raise ModelError(f"model units {name!r} are not supported; use one of {', '.join(UNIT_SCALE)}")
    return UNIT_SCALE[name]


def _xyz(p) -> list[float]:
    return [float(p.X), float(p.Y), float(p.Z)]


def curve_points(curve, segment_length: float | None = None, where: str = "curve") -> np.ndarray:
    """The vertices ``(k, 3)`` of a curve: its own for a line or polyline, else equal segments.

    A curve that is not a polyline is divided into segments of equal length,
    at most ``segment_length`` long; without ``segment_length`` it is refused
    (``where`` names it in the message).
    """
    pl = curve.TryGetPolyline() if hasattr(curve, "TryGetPolyline") else None
    if pl is not None:
        return np.array([_xyz(pl[i]) for i in range(pl.Count)], dtype=float)
    if segment_length is None:
        raise ModelError(f"{where} is a curve that is not a polyline; give segment_length to divide it")
    t0, t1 = curve.Domain.T0, curve.Domain.T1
    n_samples = _SAMPLES_PER_SPAN * max(int(getattr(curve, "SpanCount", 1)), 1) + 1
    t = np.linspace(t0, t1, n_samples)
    pts = np.array([_xyz(curve.PointAt(float(s))) for s in t])
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))])
    n = max(int(np.ceil(arc[-1] / segment_length - 1e-9)), 1)
    targets = np.linspace(0.0, arc[-1], n + 1)
    ts = np.interp(targets, arc, t)
    out = np.array([_xyz(curve.PointAt(float(s))) for s in ts])
    if curve.IsClosed:
        out[-1] = out[0]
    return out


def mesh_arrays(mesh) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Vertices ``(n, 3)``, triangles ``(t, 3)`` and quads ``(q, 4)`` of a rhino3dm mesh."""
    verts = mesh.Vertices
    points = np.array([_xyz(verts.Point3dAt(i)) for i in range(len(verts))], dtype=float).reshape(-1, 3)
    faces = np.array([tuple(mesh.Faces[i]) for i in range(mesh.Faces.Count)], dtype=np.int64).reshape(-1, 4)
    tri = faces[:, 2] == faces[:, 3]
    return points, faces[tri, :3], faces[~tri]


def merge_points(points: np.ndarray, tol: float) -> tuple[np.ndarray, np.ndarray]:
    """Points closer than ``tol`` merged: ``(unique (n, 3), index of each input point)``.

    The unique points keep the order of first appearance, at the position of
    their first point.
    """
    from scipy.spatial import cKDTree

    points = np.asarray(points, dtype=float).reshape(-1, 3)
    if len(points) == 0:
        return points, np.zeros(0, dtype=np.int64)
    if tol > 0:
        pairs = cKDTree(points).query_pairs(tol, output_type="ndarray")
    else:  # exactly equal points
        _, inverse = np.unique(points, axis=0, return_inverse=True)
        order = np.argsort(inverse.ravel(), kind="stable")
        same = inverse.ravel()[order[1:]] == inverse.ravel()[order[:-1]]
        pairs = np.stack([order[:-1][same], order[1:][same]], axis=1)
    first, index = coincident_groups(len(points), pairs)
    return points[first], index


def _layer_names(model) -> dict[int, str]:
    return {lay.Index: lay.FullPath for lay in model.Layers}


def _shown(path: Path) -> str:
    text = str(path)
    return repr(text if len(text) <= 120 else "..." + text[-117:])


def read_3dm(path, layers=None, segment_length: float | None = None, tolerance: float | None = None
             ) -> ImportedMesh:
    """Read the curves, points and meshes of a Rhino file as nodes, cells and named node sets.

    Parameters
    ----------
    path : path-like
    layers : list of str, optional
        Read only objects on these layers (full path or name; a parent takes
        its sub-layers). Default all.
    segment_length : float, optional
        Curves that are not polylines are divided into segments of at most
        this length [m]; without it they are refused.
    tolerance : float, optional
        Points closer than this [m] are one node (default the file's absolute
        tolerance, at least 1e-9 m).

    Raises
    ------
    ModelError
        The file cannot be read, holds objects that are no structural
        geometry on a read layer, names a layer it does not have, or holds
        nothing to build members from.
    """
    r3 = rhino()
    path = Path(path)
    try:
        info = path.stat()
    except (OSError, ValueError):
        raise ModelError(f"Rhino file {_shown(path)} does not exist") from None
    if not stat.S_ISREG(info.st_mode):
        raise ModelError(f"Rhino file {_shown(path)} is not a regular file")
    if info.st_size > MAX_MESH_BYTES:
        raise ModelError(f"Rhino file {_shown(path)} has {info.st_size:,} bytes; at most {MAX_MESH_BYTES:,} are read")
    model = r3.File3dm.Read(str(path))
    if model is None:
        raise ModelError(f"cannot read {_shown(path)} as a Rhino file (rhino3dm reads version 2 to 8 files)")
    scale = unit_scale(model.Settings.ModelUnitSystem)
    if tolerance is None:
        tolerance = max(float(model.Settings.ModelAbsoluteTolerance) * scale, 1.0e-9)
    names = _layer_names(model)
    wanted = _wanted_layers(names, layers)
    parts = _Parts()
    for k, obj in enumerate(model.Objects):
        layer = names.get(obj.Attributes.LayerIndex, "")
        if layer not in wanted:
            continue
        label = obj.Attributes.Name or f"object {k}"
        where = f"{label} on layer {layer!r}"
        sets = [layer] + ([obj.Attributes.GetUserString(SET_KEY)] if obj.Attributes.GetUserString(SET_KEY) else [])
        parts.add(obj.Geometry, sets, where, segment_length, scale)
    return parts.mesh(tolerance, str(path), names, wanted)


def _wanted_layers(names: dict[int, str], layers) -> set[str]:
    full = set(names.values())
    if layers is None:
        return full
    wanted = set()
    for name in layers:
        hit = {f for f in full if f == name or f.startswith(name + "::") or f.rsplit("::", 1)[-1] == name}
        if not hit:
            raise ModelError(f"the file has no layer {name[:80]!r}; its layers: "
                             + ", ".join(repr(n) for n in sorted(full)))
        wanted |= {f for f in full if any(f == h or f.startswith(h + "::") for h in hit)}
    return wanted


class _Parts:
    """Points, cells and set memberships gathered object by object, merged at the end."""

    def __init__(self):
        self.points: list[np.ndarray] = []
        self.cells: dict[str, list[np.ndarray]] = {}
        self.sets: dict[str, list[np.ndarray]] = {}
        self.loose: list[tuple[int, str]] = []  # point objects, to be checked against the members
        self.n = 0

    def _take(self, pts: np.ndarray, sets) -> np.ndarray:
        ids = np.arange(self.n, self.n + len(pts))
        self.points.append(pts)
        self.n += len(pts)
        for s in sets:
            self.sets.setdefault(s, []).append(ids)
        return ids

    def add(self, geom, sets, where: str, segment_length, scale: float) -> None:
        kind = type(geom).__name__
        if kind == "Point":
            ids = self._take(np.array([_xyz(geom.Location)]) * scale, sets)
            self.loose.append((int(ids[0]), where))
        elif kind == "PointCloud":
            pts = np.array([_xyz(geom[i].Location) for i in range(geom.Count)]).reshape(-1, 3) * scale
            ids = self._take(pts, sets)
            self.loose += [(int(i), where) for i in ids]
        elif kind in ("LineCurve", "PolylineCurve", "NurbsCurve", "ArcCurve", "PolyCurve", "Curve"):
            pts = curve_points(geom, None if segment_length is None else segment_length / scale, where) * scale
            ids = self._take(pts, sets)
            self.cells.setdefault("line", []).append(np.column_stack([ids[:-1], ids[1:]]))
        elif kind == "Mesh":
            pts, tri, quad = mesh_arrays(geom)
            ids = self._take(pts * scale, sets)
            if len(tri):
                self.cells.setdefault("triangle", []).append(ids[tri])
            if len(quad):
                self.cells.setdefault("quad", []).append(ids[quad])
        else:
            raise ModelError(f"{where} is a {kind}; a structure is read from curves, points and meshes "
                             "(put other objects on a layer that is not read)")

    def mesh(self, tolerance: float, source: str, names, wanted) -> ImportedMesh:
        if not self.cells:
            raise ModelError(f"Rhino file {source!r} holds no curves or meshes on the layers read "
                             f"({', '.join(repr(w) for w in sorted(wanted)) or 'none'})")
        raw = np.concatenate(self.points)
        if len(raw) > MAX_POINTS:
            raise ModelError(f"Rhino file {source!r} has {len(raw):,} vertices; at most {MAX_POINTS:,} are allowed")
        if not np.all(np.isfinite(raw)) or np.abs(raw).max() > MAX_COORDINATE:
            raise ModelError(f"Rhino file {source!r}: coordinates beyond {MAX_COORDINATE:.0e} m")
        points, index = merge_points(raw, tolerance)
        cells = {}
        for family, blocks in self.cells.items():
            c = index[np.concatenate(blocks)]
            if family == "line":
                c = unique_edges(c[c[:, 0] != c[:, 1]])
            cells[family] = c
        used = np.zeros(len(points), dtype=bool)
        for c in cells.values():
            used[c.ravel()] = True
        for i, where in self.loose:
            if not used[index[i]]:
                x = raw[i]
                raise ModelError(f"the point {where} at ({x[0]:.6g}, {x[1]:.6g}, {x[2]:.6g}) m lies on no curve or "
                                 f"mesh vertex (within {tolerance:.3g} m)")
        sets = {}
        for name, parts in self.sets.items():
            sets[name] = np.unique(index[np.concatenate(parts)])
        # a layer's own name too, where no other layer shares it
        short = {}
        for name in list(sets):
            short.setdefault(name.rsplit("::", 1)[-1], []).append(name)
        for leaf, full in short.items():
            if len(full) == 1 and leaf not in sets:
                sets[leaf] = sets[full[0]]
        return ImportedMesh(points, cells, sets, source)
