"""Meshes from files (meshio): nodes, member edges and named node sets.

Any format meshio reads (``.vtu``, ``.msh``, ``.obj``, ``.stl``, ...) is a
source of structural geometry: line cells are members, and the edges of
triangle and quad cells are members too (each edge once, however many faces
share it). Higher-order cells contribute their corner nodes only. Points keep
their numbering in the file, so node numbers in a scene are the file's.
"""

from __future__ import annotations

import stat
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
#: a mesh file larger than this is not a structure's geometry (2 GiB)
MAX_MESH_BYTES = 2 * 2**30
#: most points of a mesh file (as many as a scene's nodes)
MAX_POINTS = 2_000_000
#: largest coordinate magnitude [m] (as a scene's coordinates)
MAX_COORDINATE = 1.0e6


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


def _shown(path: Path) -> str:
    text = str(path)
    return repr(text if len(text) <= 120 else "..." + text[-117:])


def mesh_format(path) -> tuple[str, tuple]:
    """The extension of a mesh file and the meshio formats it stands for.

    Raises
    ------
    ModelError
        When meshio reads no format of that extension.
    """
    path = Path(path)
    suffixes = [s.lower() for s in path.suffixes[-2:]]
    for ext in ("".join(suffixes), suffixes[-1] if suffixes else ""):
        if ext in meshio.extension_to_filetypes:
            return ext, tuple(meshio.extension_to_filetypes[ext])
    known = ", ".join(sorted(meshio.extension_to_filetypes))
    ext = suffixes[-1] if suffixes else "none"
    raise ModelError(f"mesh file {_shown(path)} has extension {ext!r}, which names no mesh format; "
                     f"expected one of {known}")


def read_mesh(path, rhino: dict | None = None) -> ImportedMesh:
    """Read a mesh file: a regular file of a mesh format meshio reads, named by its extension.

    A Rhino file (``.3dm``) is read by :func:`shellform.io.rhino_import.read_3dm`
    with the keywords ``rhino`` (layers, segment length, merge tolerance).

    Raises
    ------
    ModelError
        When the file does not exist, is not a regular file (a directory,
        device or pipe), has no mesh extension, cannot be read as its format
        (the message never quotes the file's contents), holds no line,
        triangle or quad cells, or holds points out of range; the message
        names the file and what is wrong.
    """
    path = Path(path)
    if path.suffix.lower() == ".3dm":
        from .rhino_import import read_3dm

        return read_3dm(path, **(rhino or {}))
    mesh = _read_file(path)
    points = _checked_points(mesh, path)
    cells = _member_cells(mesh, len(points), path)
    return ImportedMesh(points, cells, _named_sets(mesh, len(points), path), str(path))


def _read_file(path: Path) -> meshio.Mesh:
    try:
        info = path.stat()
    except (OSError, ValueError):
        raise ModelError(f"mesh file {_shown(path)} does not exist") from None
    if not stat.S_ISREG(info.st_mode):
        raise ModelError(f"mesh file {_shown(path)} is not a regular file (a directory, device or pipe cannot be "
                         "read as a mesh)")
    ext, formats = mesh_format(path)
    if info.st_size > MAX_MESH_BYTES:
        raise ModelError(f"mesh file {_shown(path)} has {info.st_size:,} bytes; at most {MAX_MESH_BYTES:,} are "
                         "read")
    what = f"{ext[1:].upper()} ({', '.join(formats)})" if len(formats) > 1 else formats[0]
    try:
        return meshio.read(path)
    except (Exception, SystemExit):  # meshio raises many types, and exits, on unreadable files
        # its messages may quote the file (a line of it): name the format only
        raise ModelError(f"cannot read mesh file {_shown(path)} as {what}: the file is not a valid {what} "
                         "mesh") from None


def _checked_points(mesh: meshio.Mesh, path: Path) -> np.ndarray:
    """The mesh's points as finite (n, 3) coordinates in range."""
    try:
        points = np.asarray(mesh.points, dtype=float)
    except (TypeError, ValueError):
        raise ModelError(f"mesh file {_shown(path)}: its points are not numbers") from None
    if points.ndim != 2 or points.shape[1] not in (2, 3) or not len(points):
        raise ModelError(f"mesh file {_shown(path)}: points have shape {points.shape}; expected (n, 2) or (n, 3)")
    if len(points) > MAX_POINTS:
        raise ModelError(f"mesh file {_shown(path)} has {len(points):,} points; at most {MAX_POINTS:,} are allowed")
    if points.shape[1] == 2:
        points = np.column_stack([points, np.zeros(len(points))])
    if not np.all(np.isfinite(points)):
        bad = int(np.argwhere(~np.isfinite(points))[0, 0])
        raise ModelError(f"mesh file {_shown(path)}: point {bad} has a non-finite coordinate")
    far = np.flatnonzero(np.abs(points).max(axis=1) > MAX_COORDINATE)
    if far.size:
        k = int(far[0])
        raise ModelError(f"mesh file {_shown(path)}: point {k} has a coordinate of magnitude "
                         f"{np.abs(points[k]).max():.3g}; at most {MAX_COORDINATE:.0e} m is allowed")
    return points


def _member_cells(mesh: meshio.Mesh, n_points: int, path: Path) -> dict[str, np.ndarray]:
    """Corner nodes of the line, triangle and quad cells by family; any other cell type is refused."""
    cells: dict[str, list] = {}
    other = set()
    for block in mesh.cells:
        family = next((f for f, types in FAMILIES.items() if block.type in types), None)
        if family is None:
            if block.type not in _IGNORED:
                other.add(block.type)
            continue
        data = np.asarray(block.data)
        if data.ndim != 2 or data.shape[1] < CORNERS[block.type] or not np.issubdtype(data.dtype, np.integer):
            raise ModelError(f"mesh file {_shown(path)}: its {block.type} cells are not rows of point numbers")
        data = data[:, : CORNERS[block.type]].astype(np.int64)
        bad = np.argwhere((data < 0) | (data >= n_points))
        if bad.size:
            k, c = (int(v) for v in bad[0])
            raise ModelError(f"mesh file {_shown(path)}: {block.type} cell {k} refers to point {int(data[k, c])}; "
                             f"the file has {n_points} points (0..{n_points - 1})")
        cells.setdefault(family, []).append(data)
    if not cells:
        held = ", ".join(sorted(other)) or "no cells"
        raise ModelError(f"mesh file {_shown(path)} has no line, triangle or quad cells (it holds {held})")
    if other:
        raise ModelError(f"mesh file {_shown(path)}: cells of type {', '.join(sorted(other))} cannot be members; "
                         "use a mesh of lines, triangles or quads")
    return {f: np.concatenate(v) for f, v in cells.items()}


def _named_sets(mesh: meshio.Mesh, n_points: int, path: Path) -> dict[str, np.ndarray]:
    """The mesh's point sets and the nodes of its cell sets, by name."""
    sets = {}
    try:
        for name, ids in (mesh.point_sets or {}).items():
            sets[str(name)] = np.unique(np.asarray(ids, dtype=np.int64))
        for name, blocks in (mesh.cell_sets or {}).items():
            if str(name).startswith("gmsh:"):
                continue  # gmsh's bookkeeping, not a named set
            nodes = [np.asarray(mesh.cells[i].data)[np.asarray(ids, dtype=np.int64)].ravel()
                     for i, ids in enumerate(blocks) if ids is not None and len(ids)]
            if nodes:
                sets.setdefault(str(name), np.unique(np.concatenate(nodes)))
    except (TypeError, ValueError, IndexError):
        raise ModelError(f"mesh file {_shown(path)}: its named sets refer to cells or points it does not "
                         "have") from None
    for name, ids in sets.items():
        if ids.size and (ids[0] < 0 or ids[-1] >= n_points):
            raise ModelError(f"mesh file {_shown(path)}: the named set {name[:60]!r} refers to point "
                             f"{int(ids[0] if ids[0] < 0 else ids[-1])}; the file has {n_points} points")
    return sets
