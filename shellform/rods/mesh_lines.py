"""Rods along the edge chains of a mesh, and the surface normal that orients their sections.

On a quad mesh a *chain* is what a designer sees as one grid line: from an
edge it goes straight on through a node to the one edge there that shares
no quad with it (at a regular interior node, the opposite edge; along the
boundary, the next boundary edge) and ends where there is no such edge or
more than one (a corner, an irregular node, a boundary reached across).
Line cells chain through nodes where exactly two line cells meet. A chain
that comes back to its first edge is a closed rod.

Building a network is done once, so the chains are followed edge by edge;
nothing here runs in a solver's loop.
"""

from __future__ import annotations

from collections import defaultdict

import numpy as np

from ..errors import ModelError


def _next_edges(quads: np.ndarray, lines: np.ndarray, n_nodes: int):
    """For every directed step ``(a, b)``, the node after ``b`` on the same chain (or none)."""
    face_edges = defaultdict(set)  # undirected edge -> quads that hold it
    at_node = defaultdict(set)  # node -> its quad edges
    for f, quad in enumerate(quads):
        for k in range(4):
            e = tuple(sorted((int(quad[k]), int(quad[(k + 1) % 4]))))
            face_edges[e].add(f)
            at_node[e[0]].add(e)
            at_node[e[1]].add(e)
    line_at = defaultdict(set)
    for a, b in lines:
        e = tuple(sorted((int(a), int(b))))
        if e not in face_edges:
            line_at[e[0]].add(e)
            line_at[e[1]].add(e)

    def after(a: int, b: int) -> int | None:
        e = tuple(sorted((a, b)))
        if e in face_edges:
            faces = face_edges[e]
            ahead = [o for o in at_node[b] if o != e and not (face_edges[o] & faces)]
        else:
            ahead = [o for o in line_at[b] if o != e] if len(line_at[b]) == 2 else []
        if len(ahead) != 1:
            return None
        o = ahead[0]
        return o[1] if o[0] == b else o[0]

    edges = list(face_edges) + [e for node in line_at.values() for e in node if e not in face_edges]
    return after, list(dict.fromkeys(edges))


def edge_chains(n_nodes: int, quads=None, lines=None) -> list[tuple[np.ndarray, bool]]:
    """Node chains of a mesh's quads and line cells: ``(nodes, closed)`` for every rod.

    Parameters
    ----------
    n_nodes : int
    quads : array_like (q, 4), optional
        Quad cells, corners in order around the face.
    lines : array_like (l, 2), optional
        Line cells.

    Returns
    -------
    list of (ndarray, bool)
        Every mesh edge lies on exactly one chain. A chain that would pass a
        node twice without closing is cut there.
    """
    quads = np.zeros((0, 4), dtype=np.int64) if quads is None else np.asarray(quads, dtype=np.int64)
    lines = np.zeros((0, 2), dtype=np.int64) if lines is None else np.asarray(lines, dtype=np.int64)
    if quads.ndim != 2 or quads.shape[1] != 4 or lines.ndim != 2 or lines.shape[1] != 2:
        raise ModelError("edge chains: quads must be (q, 4) and lines (l, 2) node numbers")
    after, edges = _next_edges(quads, lines, n_nodes)
    used: set = set()
    chains = []
    for a, b in edges:
        if (a, b) in used:
            continue
        used.add((a, b))
        forward = _walk(a, b, after, used)
        if forward and forward[-1] == a:  # back at the start: a ring
            chains.append((np.array([a, b] + forward[:-1], dtype=np.int64), True))
            continue
        backward = _walk(b, a, after, used)
        nodes = backward[::-1] + [a, b] + forward
        chains.append((np.array(nodes, dtype=np.int64), False))
    return chains


def _walk(a: int, b: int, after, used: set) -> list[int]:
    """Nodes beyond ``b`` going on from ``a -> b`` until the chain ends, marking the edges used."""
    out = []
    seen = {a, b}
    while True:
        c = after(a, b)
        if c is None or tuple(sorted((b, c))) in used:
            return out
        used.add(tuple(sorted((b, c))))
        out.append(c)
        if c in seen:
            return out  # closed (c is the start) or crossing itself; the caller decides
        seen.add(c)
        a, b = b, c


def vertex_normals(points: np.ndarray, faces) -> np.ndarray:
    """Unit normals at the nodes: area-weighted sums of the normals of the faces (triangles, quads) around them.

    Nodes on no face get zero vectors. Faces are taken as oriented in the
    file (corners counter-clockwise seen from the side the normal points to).
    """
    n = np.zeros_like(points, dtype=float)
    for f in faces:
        f = np.asarray(f, dtype=np.int64)
        if not len(f):
            continue
        if f.shape[1] == 3:
            w = np.cross(points[f[:, 1]] - points[f[:, 0]], points[f[:, 2]] - points[f[:, 0]])
        else:  # a quad's diagonals: twice its vector area
            w = np.cross(points[f[:, 2]] - points[f[:, 0]], points[f[:, 3]] - points[f[:, 1]])
        for k in range(f.shape[1]):
            np.add.at(n, f[:, k], w)
    size = np.linalg.norm(n, axis=1)
    return np.divide(n, size[:, None], out=np.zeros_like(n), where=size[:, None] > 0)


def chain_directors(points: np.ndarray, chain: np.ndarray, closed: bool, node_normals: np.ndarray) -> np.ndarray:
    """One director per edge of a chain: the mean normal of its two nodes, of one sign along the chain.

    A mesh whose faces are not consistently oriented gives normals of either
    sign; each edge's director is turned to agree with the one before it, and
    the first to point up (positive z) where it is not horizontal.
    """
    a = chain
    b = np.roll(chain, -1) if closed else chain[1:]
    a = a[: len(b)]
    d = node_normals[a] + node_normals[b]
    for k in range(1, len(d)):
        if d[k] @ d[k - 1] < 0:
            d[k] = -d[k]
    if d[0, 2] < 0:
        d = -d
    return d
