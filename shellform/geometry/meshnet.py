"""An unstructured net: nodes, the faces or lines that join them, and named node sets.

A :class:`MeshNet` is what form finding needs of any net that is not a
structured grid: a gmsh planform meshed with unstructured quads or triangles
(:mod:`shellform.geometry.planforms`) or a mesh file of quads, triangles or
lines. Its edges (each once) become ropes; ``"boundary"`` holds the nodes on
edges of exactly one face (the ends of a line mesh) and ``"corners"`` the
boundary nodes where the boundary turns by more than :data:`CORNER_ANGLE`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import ModelError

#: a boundary node is a corner where the boundary turns by more than this [degrees]
CORNER_ANGLE = 30.0


@dataclass
class MeshNet:
    """Nodes and cells of an unstructured net.

    Attributes
    ----------
    nodes : ndarray, shape (n, 3)
    quads : ndarray, shape (m, 4)
    triangles : ndarray, shape (k, 3)
    lines : ndarray, shape (l, 2)
        Line cells (a net of lines, or edge lines of a mesh).
    groups : dict of str to ndarray
        Named node sets; ``"boundary"`` and ``"corners"`` are filled in when absent.
    """

    nodes: np.ndarray
    quads: np.ndarray = field(default_factory=lambda: np.zeros((0, 4), dtype=np.int64))
    triangles: np.ndarray = field(default_factory=lambda: np.zeros((0, 3), dtype=np.int64))
    lines: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), dtype=np.int64))
    groups: dict = field(default_factory=dict)

    #: no structured (i, j) positions, grid lines or coarser lattice
    structured = False

    def __post_init__(self):
        self.nodes = np.asarray(self.nodes, dtype=float)
        self.quads = np.asarray(self.quads, dtype=np.int64).reshape(-1, 4)
        self.triangles = np.asarray(self.triangles, dtype=np.int64).reshape(-1, 3)
        self.lines = np.asarray(self.lines, dtype=np.int64).reshape(-1, 2)
        cells = np.concatenate([self.quads.ravel(), self.triangles.ravel(), self.lines.ravel()])
        if not cells.size:
            raise ModelError("net: the mesh has no quads, triangles or lines")
        if cells.min() < 0 or cells.max() >= len(self.nodes):
            raise ModelError(f"net: a cell refers to node {int(cells.max())}; the mesh has {len(self.nodes)} nodes")
        self.edges = _unique_edges(np.concatenate([_cycle(self.quads), _cycle(self.triangles), self.lines]))
        if np.any(self.edges[:, 0] == self.edges[:, 1]):
            raise ModelError("net: a cell joins a node to itself")
        self.groups = {k: np.unique(np.asarray(v, dtype=np.int64)) for k, v in self.groups.items()}
        self.groups.setdefault("boundary", self._boundary())
        self.groups.setdefault("corners", self._corners())

    @property
    def n_nodes(self) -> int:
        return len(self.nodes)

    @property
    def boundary(self) -> np.ndarray:
        return self.groups["boundary"]

    @property
    def faces(self) -> dict:
        """Face cells by type (``"quad"``, ``"triangle"``), those present only."""
        return {k: v for k, v in (("quad", self.quads), ("triangle", self.triangles)) if len(v)}

    def group(self, name: str) -> np.ndarray:
        try:
            return self.groups[name]
        except KeyError:
            raise ModelError(f"net: no node set named {name!r}; available: {sorted(self.groups)}") from None

    def edge_direction(self) -> np.ndarray:
        """One family for every edge (an unstructured net has no grid lines)."""
        return np.zeros(len(self.edges), dtype=np.int8)

    def boundary_edges(self) -> np.ndarray:
        """Edges of exactly one face; of a net of lines, every line."""
        faces = np.concatenate([_cycle(self.quads), _cycle(self.triangles)])
        if not len(faces):
            return self.edges.copy()
        e, counts = np.unique(np.sort(faces, axis=1), axis=0, return_counts=True)
        return e[counts == 1]

    def _boundary(self) -> np.ndarray:
        if len(self.quads) or len(self.triangles):
            return np.unique(self.boundary_edges())
        degree = np.bincount(self.edges.ravel(), minlength=self.n_nodes)
        return np.flatnonzero(degree == 1)

    def _corners(self) -> np.ndarray:
        """Boundary nodes with two boundary neighbours where the boundary turns by more than CORNER_ANGLE."""
        if not (len(self.quads) or len(self.triangles)):
            return self.groups["boundary"]
        be = self.boundary_edges()
        nbr = {}
        for a, b in be:
            nbr.setdefault(int(a), []).append(int(b))
            nbr.setdefault(int(b), []).append(int(a))
        out = []
        for i, ns in nbr.items():
            if len(ns) != 2:
                out.append(i)  # where boundary loops touch
                continue
            u = self.nodes[i] - self.nodes[ns[0]]
            v = self.nodes[ns[1]] - self.nodes[i]
            c = float(u @ v) / max(float(np.linalg.norm(u) * np.linalg.norm(v)), 1e-300)
            if np.degrees(np.arccos(np.clip(c, -1.0, 1.0))) > CORNER_ANGLE:
                out.append(i)
        return np.array(sorted(out), dtype=np.int64)


def _cycle(cells: np.ndarray) -> np.ndarray:
    """The edges of face cells, each face's corners in cyclic order."""
    if not len(cells):
        return np.zeros((0, 2), dtype=np.int64)
    return np.stack([cells, np.roll(cells, -1, axis=1)], axis=2).reshape(-1, 2)


def _unique_edges(edges: np.ndarray) -> np.ndarray:
    """Each undirected edge once, smaller node first, sorted."""
    e = np.sort(np.asarray(edges, dtype=np.int64).reshape(-1, 2), axis=1)
    return np.unique(e, axis=0) if len(e) else e


def mesh_net(points, cells: dict, point_sets: dict | None = None) -> MeshNet:
    """A :class:`MeshNet` from a mesh's points, cells by family (``"quad"``, ``"triangle"``, ``"line"``) and
    named node sets; nodes no cell uses are refused (they would hang unheld)."""
    points = np.asarray(points, dtype=float)
    quads = cells.get("quad", np.zeros((0, 4), dtype=np.int64))
    tris = cells.get("triangle", np.zeros((0, 3), dtype=np.int64))
    lines = cells.get("line", np.zeros((0, 2), dtype=np.int64))
    used = np.zeros(len(points), dtype=bool)
    for c in (quads, tris, lines):
        used[np.asarray(c, dtype=np.int64)[:, :c.shape[1]].ravel()] = True
    if not used.all():
        k = int(np.flatnonzero(~used)[0])
        raise ModelError(f"net: node {k} (and {int((~used).sum()) - 1} more) belongs to no quad, triangle or line; "
                         "a net node must hang from ropes")
    return MeshNet(points, quads, tris, lines, dict(point_sets or {}))
