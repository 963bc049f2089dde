"""Meshes from files (meshio): nodes, member edges and named node sets.

Any format meshio reads (``.vtu``, ``.msh``, ``.obj``, ``.stl``, ...) is a
source of structural geometry: line cells are members, and the edges of
triangle and quad cells are members too (each edge once, however many faces
share it). Higher-order cells contribute their corner nodes only. Points keep
their numbering in the file, so node numbers in a scene are the file's.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import meshio
import numpy as np

from ..errors import ModelError

#: cell types that give members, and the corner nodes of each in cyclic order
CORNERS = {
    "line": 2, "line3": 2,
    "triangle": 3, "triangle6": 3, "triangle7": 3,
    "quad": 4, "quad8": 4, "quad9": 4,
}
#: the families of cell types a scene selects members by
FAMILIES = {"line": ("line", "line3"), "triangle": ("triangle", "triangle6", "triangle7"),
            "quad": ("quad", "quad8", "quad9")}
_IGNORED = {"vertex"}


@dataclass
class ImportedMesh:
    """Geometry read from a mesh file.

    Attributes
    ----------
    points : ndarray (n, 3)
    cells : dict of family ("line", "triangle", "quad") to ndarray (m, k) of corner nodes
    point_sets : dict of str to ndarray
        Named node sets of the file (meshio point sets, and the nodes of
        named cell sets such as gmsh physical groups).
    source : str
    """

    points: np.ndarray
    cells: dict
    point_sets: dict = field(default_factory=dict)
    source: str = ""

    def edges(self, families=None) -> np.ndarray:
        """Unique edges ``(m, 2)`` of the cells of the given families (default all), in file order."""
        families = tuple(self.cells) if families is None else tuple(families)
        parts = [_cycle_edges(self.cells[f], f) for f in families if f in self.cells]
        if not parts:
            return np.zeros((0, 2), dtype=np.int64)
        return unique_edges(np.concatenate(parts))

    def boundary_nodes(self) -> np.ndarray:
        """Nodes on the boundary: edges of exactly one surface cell; for line meshes, line ends."""
        faces = [_cycle_edges(self.cells[f], f) for f in ("triangle", "quad") if f in self.cells]
        if faces:
            e = np.sort(np.concatenate(faces), axis=1)
            uniq, counts = np.unique(e, axis=0, return_counts=True)
            return np.unique(uniq[counts == 1])
        if "line" in self.cells:
            e = unique_edges(_cycle_edges(self.cells["line"], "line"))
            degree = np.bincount(e.ravel(), minlength=len(self.points))
            return np.flatnonzero(degree == 1)
        return np.zeros(0, dtype=np.int64)


def _cycle_edges(cells: np.ndarray, family: str) -> np.ndarray:
    if family == "line":
        return cells[:, :2]
    k = cells.shape[1]
    return np.stack([cells, np.roll(cells, -1, axis=1)], axis=2).reshape(-1, 2) if k else cells


def unique_edges(edges: np.ndarray) -> np.ndarray:
    """Each undirected edge once (smaller node first), in order of first appearance."""
    e = np.sort(np.asarray(edges, dtype=np.int64), axis=1)
    if not len(e):
        return e.reshape(0, 2)
    _, first = np.unique(e, axis=0, return_index=True)
    return e[np.sort(first)]


def read_mesh(path) -> ImportedMesh:
    """Read a mesh file.

    Raises
    ------
    ModelError
        When the file cannot be read or holds no line, triangle or quad cells;
        the message names the file and what it holds.
    """
    path = Path(path)
    if not path.is_file():
        raise ModelError(f"mesh file {str(path)!r} does not exist")
    try:
        mesh = meshio.read(path)
    except (Exception, SystemExit) as exc:  # meshio raises many types, and exits, on unreadable files
        reason = f"{exc}" if not isinstance(exc, SystemExit) else "not a valid file of its format"
        raise ModelError(f"cannot read mesh file {str(path)!r}: {reason}") from None
    points = np.asarray(mesh.points, dtype=float)
    if points.ndim != 2 or points.shape[1] not in (2, 3) or not len(points):
        raise ModelError(f"mesh file {str(path)!r}: points have shape {points.shape}; expected (n, 2) or (n, 3)")
    if points.shape[1] == 2:
        points = np.column_stack([points, np.zeros(len(points))])
    if not np.all(np.isfinite(points)):
        bad = int(np.argwhere(~np.isfinite(points))[0, 0])
        raise ModelError(f"mesh file {str(path)!r}: point {bad} has a non-finite coordinate")
    cells: dict[str, list] = {}
    other = set()
    for block in mesh.cells:
        family = next((f for f, types in FAMILIES.items() if block.type in types), None)
        if family is None:
            if block.type not in _IGNORED:
                other.add(block.type)
            continue
        cells.setdefault(family, []).append(np.asarray(block.data, dtype=np.int64)[:, : CORNERS[block.type]])
    if not cells:
        held = ", ".join(sorted(other)) or "no cells"
        raise ModelError(f"mesh file {str(path)!r} has no line, triangle or quad cells (it holds {held})")
    if other:
        raise ModelError(f"mesh file {str(path)!r}: cells of type {', '.join(sorted(other))} cannot be members; "
                         "use a mesh of lines, triangles or quads")
    sets = {str(k): np.unique(np.asarray(v, dtype=np.int64)) for k, v in (mesh.point_sets or {}).items()}
    for name, blocks in (mesh.cell_sets or {}).items():
        if str(name).startswith("gmsh:"):
            continue  # gmsh's bookkeeping, not a named set
        nodes = [np.asarray(mesh.cells[i].data)[np.asarray(ids, dtype=np.int64)].ravel()
                 for i, ids in enumerate(blocks) if ids is not None and len(ids)]
        if nodes:
            sets.setdefault(str(name), np.unique(np.concatenate(nodes)))
    return ImportedMesh(points, {f: np.concatenate(v) for f, v in cells.items()}, sets, str(path))
