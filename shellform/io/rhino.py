"""Rhino ``.3dm`` export (optional extra: ``pip install shellform[rhino]``).

Members become line curves, rod centrelines polylines and surfaces (the
inverted shell of a form-found net) meshes, each on a named layer, so the
result opens in Rhino and feeds Grasshopper. Model units are metres.

A state (:func:`structure_3dm`, :func:`state_3dm`) carries its results: every
member is one line on the layer of its group (``members::<group>``) with its
results as user text (``axial_force [N]``, ``slack [-]``,
``bending_moment [N m]``, ... the cell fields of
:func:`shellform.io.mesh.state_mesh`, a field a member does not have left
out), the supported nodes are points on the layer ``supports`` with their
reaction as user text, the reactions are lines on the layer ``reactions``
(drawn at a scale stated in the document's user text), and every buckling
mode is a layer of its own (``mode K``: the members at the critical state
moved by the mode times a stated scale).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from .files import atomic_target
from .units import FIELD_UNITS

#: the layer of the supported nodes, and of the reactions drawn as lines
SUPPORTS_LAYER = "supports"
REACTIONS_LAYER = "reactions"


def _rhino():
    try:
        import rhino3dm
    except ImportError:  # pragma: no cover
        raise ImportError("Rhino export needs rhino3dm: pip install 'shellform[rhino]'") from None
    return rhino3dm


def _number(v: float) -> str:
    return repr(float(v))


def user_key(name: str) -> str:
    """The user text key of a result field: its name and unit, as in the CSV headers (``axial_force [N]``)."""
    return f"{name} [{FIELD_UNITS.get(name, '-')}]"


class _Document:
    """A Rhino model in metres, with layers made on first use."""

    def __init__(self):
        self.r3 = _rhino()
        self.model = self.r3.File3dm()
        self.model.Settings.ModelUnitSystem = self.r3.UnitSystem.Meters
        self.layers: dict[str, int] = {}

    def layer(self, path: str) -> int:
        """The index of a layer (``parent::child`` makes the parent too)."""
        if path not in self.layers:
            parent, _, name = path.rpartition("::")
            lay = self.r3.Layer()
            lay.Name = name
            if parent:
                lay.ParentLayerId = self.model.Layers.FindIndex(self.layer(parent)).Id
            self.layers[path] = self.model.Layers.Add(lay)
        return self.layers[path]

    def attributes(self, layer: str, name: str = "", text: dict | None = None):
        attrs = self.r3.ObjectAttributes()
        attrs.LayerIndex = self.layer(layer)
        if name:
            attrs.Name = name
        for key, value in (text or {}).items():
            attrs.SetUserString(key, value)
        return attrs

    def point(self, p):
        return self.r3.Point3d(*map(float, p))

    def line(self, layer, a, b, name="", text=None):
        self.model.Objects.AddLine(self.point(a), self.point(b), self.attributes(layer, name, text))

    def polyline(self, layer, pts, name="", text=None):
        pl = self.r3.Point3dList()
        for p in np.asarray(pts, dtype=float):
            pl.Add(*p)
        self.model.Objects.AddPolyline(pl, self.attributes(layer, name, text))

    def mark(self, layer, p, name="", text=None):
        self.model.Objects.AddPoint(self.point(p), self.attributes(layer, name, text))

    def mesh(self, layer, pts, faces, name=""):
        mesh = self.r3.Mesh()
        for p in np.asarray(pts, dtype=float):
            mesh.Vertices.AddPoint3d(*map(float, p))  # double precision
        for f in np.asarray(faces, dtype=int):
            mesh.Faces.AddFace(*map(int, f))
        mesh.Normals.ComputeNormals()
        self.model.Objects.AddMesh(mesh, self.attributes(layer, name))

    def note(self, key: str, value: str):
        """Document user text."""
        self.model.Strings[key] = value

    def write(self, path) -> Path:
        path = Path(path)
        with atomic_target(path) as tmp:
            if not self.model.Write(str(tmp), 7):
                raise OSError(f"rhino3dm could not write {path}")
        return path


def write_3dm(
    path,
    lines: dict[str, tuple[np.ndarray, np.ndarray]] | None = None,
    polylines: dict[str, Sequence[np.ndarray]] | None = None,
    meshes: dict[str, tuple[np.ndarray, np.ndarray]] | None = None,
    line_text: dict[str, dict[str, np.ndarray]] | None = None,
) -> Path:
    """Write geometry to a Rhino file (atomically).

    Parameters
    ----------
    lines : dict layer -> (points (n, 3), connectivity (m, 2))
    polylines : dict layer -> list of (k, 3) point arrays
    meshes : dict layer -> (points (n, 3), faces (f, 3 or 4))
    line_text : dict layer -> {user text key: values (m,)}
        Per-line user text of a layer of ``lines``; NaN values are left out.
    """
    doc = _Document()
    for name, (pts, conn) in (lines or {}).items():
        _lines(doc, name, pts, conn, (line_text or {}).get(name, {}))
    for name, curves in (polylines or {}).items():
        for k, pts in enumerate(curves):
            doc.polyline(name, pts, f"{name} {k}")
    for name, (pts, faces) in (meshes or {}).items():
        doc.mesh(name, pts, faces, name)
    return doc.write(path)


def _lines(doc: _Document, layer: str, pts, conn, fields: dict, start: int = 0, extra: dict | None = None):
    pts = np.asarray(pts, dtype=float)
    conn = np.asarray(conn, dtype=np.int64).reshape(-1, 2)
    values = {k: np.asarray(v) for k, v in fields.items()}
    for m, (a, b) in enumerate(conn):
        text = {"member": str(start + m), **(extra or {})}
        text.update({k: str(int(v[m])) if v.dtype.kind in "biu" else _number(v[m])
                     for k, v in values.items() if v.dtype.kind in "biu" or np.isfinite(v[m])})
        doc.line(layer, pts[a], pts[b], f"{layer} {m}", text)


def _span(x: np.ndarray) -> float:
    return float(np.ptp(x, axis=0).max()) if len(x) else 0.0


def state_3dm(path, mesh, group_names: Sequence[str], supported: np.ndarray | None = None,
              modes: Sequence[tuple[str, object]] = (), member_text: dict[str, np.ndarray] | None = None) -> Path:
    """Write a state mesh (:func:`~shellform.io.mesh.state_mesh`) with its results as user text.

    Parameters
    ----------
    mesh : meshio.Mesh
        Line cells with cell data (``group``, results) and point data
        (``reaction``).
    group_names : list of str
        Names of the member groups, by the ``group`` numbers of the cells.
    supported : ndarray of bool (n, 3), optional
        Fixed translations of every node: nodes with any become support points.
    modes : list of (label, meshio.Mesh)
        Critical states with their buckling mode as point data ``mode``; each
        becomes the layer ``label``: the members at the critical state moved by
        the mode times a scale (a tenth of the structure's span, in the
        document's user text ``mode_scale [m]``).
    member_text : dict, optional
        Further per-member user text (values per line cell; NaN left out),
        e.g. ``length_class [-]``.
    """
    doc = _Document()
    x = np.asarray(mesh.points, dtype=float)
    lines = np.asarray(mesh.cells[0].data, dtype=np.int64)
    fields = {k: np.asarray(v[0], dtype=float) for k, v in mesh.cell_data.items()}
    group = fields.pop("group").astype(int) if "group" in fields else np.zeros(len(lines), dtype=int)
    text = {user_key(k): v for k, v in fields.items()}
    text.update(member_text or {})
    for g in np.unique(group):
        rows = np.flatnonzero(group == g)
        name = "joints" if g < 0 else f"members::{group_names[g] if g < len(group_names) else f'group {g}'}"
        for r in rows:
            vals = {"member": str(int(r)), **{k: _number(v[r]) for k, v in text.items() if np.isfinite(v[r])}}
            doc.line(name, x[lines[r, 0]], x[lines[r, 1]], f"member {int(r)}", vals)
    span = _span(x)
    reaction = mesh.point_data.get("reaction")
    if supported is not None and np.any(supported):
        nodes = np.flatnonzero(np.any(supported, axis=1))
        R = np.asarray(reaction, dtype=float) if reaction is not None else np.full((len(x), 3), np.nan)
        big = np.linalg.norm(R[nodes], axis=1).max() if len(nodes) and reaction is not None else 0.0
        scale = 0.1 * span / big if big > 0 else 0.0
        for n in nodes:
            vals = {"node": str(int(n)), "dofs": "".join(c for c, f in zip("xyz", supported[n]) if f)}
            if reaction is not None:
                vals.update({f"reaction_{c} [N]": _number(R[n, i]) for i, c in enumerate("xyz")})
            doc.mark(SUPPORTS_LAYER, x[n], f"support {int(n)}", vals)
            if scale > 0 and np.linalg.norm(R[n]) > 0:
                doc.line(REACTIONS_LAYER, x[n], x[n] + scale * R[n], f"reaction {int(n)}",
                         {"node": str(int(n)), "reaction [N]": _number(np.linalg.norm(R[n]))})
        doc.note("reaction_scale [m/N]", _number(scale))
    mode_scale = 0.1 * span
    for label, crit in modes:
        xc = np.asarray(crit.points, dtype=float)
        moved = xc + mode_scale * np.asarray(crit.point_data["mode"], dtype=float)
        for r, (a, b) in enumerate(np.asarray(crit.cells[0].data, dtype=np.int64)):
            doc.line(label, moved[a], moved[b], f"{label} member {r}", {"member": str(r)})
    if modes:
        doc.note("mode_scale [m]", _number(mode_scale))
    doc.note("units", "SI: lengths m, forces N, moments N m")
    return doc.write(path)


def critical_modes(folder, stem: str = "path") -> list[tuple[str, object]]:
    """The critical states with their modes that a traced path wrote to ``folder``, labelled ``mode K``.

    The states are those its events file (``{stem}_events.json``) lists.
    """
    import json

    import meshio

    events = Path(folder) / f"{stem}_events.json"
    if not events.is_file():
        return []
    found = []
    for e in json.loads(events.read_text()).get("events", []):
        f = Path(folder) / str(e.get("file", ""))
        if e.get("file") and f.is_file():
            mesh = meshio.read(f)
            if "mode" in mesh.point_data:
                found.append((f"mode {e.get('number', len(found) + 1)} ({e.get('kind', 'critical')} point)", mesh))
    return found


def structure_3dm(path, system, q: np.ndarray, lam: float = 1.0, modes: Sequence[tuple[str, object]] | None = None
                  ) -> Path:
    """A structure at state ``q`` with its member results, supports, reactions and buckling modes
    (``modes``: see :func:`state_3dm` and :func:`critical_modes`)."""
    from .mesh import state_mesh

    s = system.structure
    supported = np.zeros((s.n_nodes, 3), dtype=bool)
    fixed = s.fixed_dofs
    fixed = fixed[fixed < 3 * s.n_nodes]
    supported.ravel()[fixed] = True
    return state_3dm(path, state_mesh(system, q, lam), [g.name for g in s.groups], supported, modes or ())
