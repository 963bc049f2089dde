"""Structured quadrilateral grids from gmsh: rectangles, discs, ellipses, B-spline surfaces.

Every generator builds one four-sided gmsh surface, meshes it with transfinite
lines and recombination (so the result is a structured grid of quads), and
returns a :class:`QuadGrid`: node coordinates, the quads, the quad edges (the
ropes of a hanging net), the boundary nodes, named node sets (sides,
corners) and the structured ``(i, j)`` index of every node.

gmsh is driven through :func:`gmsh_session`, which initialises it without
reading configuration files, silences its terminal output, and always
removes the model (and finalises gmsh when it started it), even when meshing
fails.
"""

from __future__ import annotations

import contextlib
import signal
import threading
from dataclasses import dataclass, field

import numpy as np

from ..errors import ModelError

SIDES = ("south", "east", "north", "west")
CORNERS = ("sw", "se", "ne", "nw")


@dataclass
class QuadGrid:
    """A structured quad grid.

    Attributes
    ----------
    nodes : ndarray, shape (n, 3)
        Node coordinates.
    quads : ndarray, shape (m, 4)
        Node indices of each quad, counter-clockwise.
    edges : ndarray, shape (e, 2)
        Unique quad edges, ``edges[:, 0] < edges[:, 1]``.
    ij : ndarray, shape (n, 2)
        Structured index of every node: ``i`` from the west side (0) to the
        east side (``shape[0] - 1``), ``j`` from south to north.
    shape : (int, int)
        Nodes per grid line in the ``i`` and ``j`` directions.
    groups : dict of str to ndarray
        Named node sets: ``"boundary"``, the sides ``"south"``, ``"east"``,
        ``"north"``, ``"west"`` (ordered along the side), the corners
        ``"sw"``, ``"se"``, ``"ne"``, ``"nw"`` (one node each) and
        ``"corners"``.
    """

    nodes: np.ndarray
    quads: np.ndarray
    edges: np.ndarray
    ij: np.ndarray
    shape: tuple[int, int]
    groups: dict[str, np.ndarray] = field(default_factory=dict)

    #: the grid has structured (i, j) positions, grid lines and coarser lattices
    structured = True

    @property
    def n_nodes(self) -> int:
        return len(self.nodes)

    @property
    def faces(self) -> dict:
        """Face cells by type: the quads."""
        return {"quad": self.quads}

    def boundary_edges(self) -> np.ndarray:
        """Edges of exactly one quad (smaller node first)."""
        e = np.sort(np.concatenate([self.quads[:, [0, 1]], self.quads[:, [1, 2]], self.quads[:, [2, 3]],
                                    self.quads[:, [3, 0]]]), axis=1)
        uniq, counts = np.unique(e, axis=0, return_counts=True)
        return uniq[counts == 1]

    @property
    def boundary(self) -> np.ndarray:
        return self.groups["boundary"]

    def index(self) -> np.ndarray:
        """Node number at every structured position: ``index()[i, j]``."""
        out = np.full(self.shape, -1, dtype=np.int64)
        out[self.ij[:, 0], self.ij[:, 1]] = np.arange(self.n_nodes)
        return out

    def edge_direction(self) -> np.ndarray:
        """0 for edges along ``i`` (constant ``j``), 1 for edges along ``j``."""
        d = self.ij[self.edges[:, 1]] - self.ij[self.edges[:, 0]]
        return (d[:, 0] == 0).astype(np.int8)

    def nodes_at(self, positions) -> np.ndarray:
        """Node numbers at structured positions ``[(i, j), ...]`` (negative indices count from the end)."""
        pos = np.atleast_2d(np.asarray(positions, dtype=np.int64))
        ni, nj = self.shape
        i = np.where(pos[:, 0] < 0, pos[:, 0] + ni, pos[:, 0])
        j = np.where(pos[:, 1] < 0, pos[:, 1] + nj, pos[:, 1])
        if np.any((i < 0) | (i >= ni) | (j < 0) | (j >= nj)):
            raise ModelError(f"grid position out of range: the grid has {ni} x {nj} nodes, got {positions}")
        return self.index()[i, j]

    def group(self, name: str) -> np.ndarray:
        try:
            return self.groups[name]
        except KeyError:
            raise ModelError(f"grid: no node set named {name!r}; available: {sorted(self.groups)}") from None

    def lattice(self, i_lines, j_lines) -> tuple[QuadGrid, np.ndarray]:
        """The coarser grid of the nodes where the chosen grid lines cross.

        Parameters
        ----------
        i_lines, j_lines : array_like of int
            Increasing structured indices of the kept lines (each must hold
            the first and the last line, so the sides stay the sides).

        Returns
        -------
        grid : QuadGrid
            The crossings, structured by their rank along the kept lines; its
            edges join neighbouring crossings.
        source : ndarray of int
            Node ``k`` of ``grid`` is node ``source[k]`` of this grid.
        """
        rows = []
        for name, lines, n in (("i", i_lines, self.shape[0]), ("j", j_lines, self.shape[1])):
            lines = np.asarray(lines, dtype=np.int64)
            if (lines.ndim != 1 or len(lines) < 2 or lines[0] != 0 or lines[-1] != n - 1
                    or np.any(np.diff(lines) <= 0)):
                raise ModelError(f"grid lattice: the {name} lines must increase from 0 to {n - 1}, "
                                 f"got {lines.tolist()}")
            rows.append(lines)
        ni, nj = len(rows[0]), len(rows[1])
        source = self.index()[np.ix_(rows[0], rows[1])]  # (ni, nj) fine node numbers
        index = np.arange(ni * nj).reshape(ni, nj)
        quads = np.column_stack([index[:-1, :-1].ravel(), index[1:, :-1].ravel(),
                                 index[1:, 1:].ravel(), index[:-1, 1:].ravel()])
        edges = np.concatenate([np.column_stack([index[:-1, :].ravel(), index[1:, :].ravel()]),
                                np.column_stack([index[:, :-1].ravel(), index[:, 1:].ravel()])])
        I, J = np.meshgrid(np.arange(ni), np.arange(nj), indexing="ij")
        groups = {"south": index[:, 0].copy(), "north": index[:, -1].copy(),
                  "west": index[0, :].copy(), "east": index[-1, :].copy(),
                  "sw": index[[0], 0], "se": index[[-1], 0], "ne": index[[-1], -1], "nw": index[[0], -1]}
        groups["corners"] = np.concatenate([groups[c] for c in CORNERS])
        groups["boundary"] = np.unique(np.concatenate([groups[s] for s in SIDES]))
        source = source.ravel()
        grid = QuadGrid(nodes=self.nodes[source].copy(), quads=quads, edges=np.sort(edges, axis=1),
                        ij=np.column_stack([I.ravel(), J.ravel()]), shape=(ni, nj), groups=groups)
        return grid, source


@contextlib.contextmanager
def gmsh_session(name: str = "shellform"):
    """Run gmsh quietly for one model; clean up whatever happens.

    gmsh keeps global state: we initialise it only if nobody else has, never
    read the user's option files, install no signal handler (``interruptible
    = False``, so it also works outside the main thread), and remove the model
    and finalise on exit.
    """
    import gmsh

    own = not gmsh.isInitialized()
    if own:
        pipe = getattr(signal, "SIGPIPE", None)
        previous = signal.getsignal(pipe) if pipe is not None else None
        gmsh.initialize(readConfigFiles=False, interruptible=False)
        if pipe is not None:
            _restore_signal(pipe, previous)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.option.setNumber("General.Verbosity", 1)
        gmsh.model.add(name)
        yield gmsh
    finally:
        try:
            gmsh.model.remove()
        finally:
            if own:
                gmsh.finalize()


def _restore_signal(number, previous):
    """Give a signal back the disposition it had before gmsh started.

    gmsh's first initialisation sets SIGPIPE back to the system default, which
    ends the process. Python ignores it, so that a write to a pipe or a socket
    whose reader has gone raises an error instead: a process pool whose worker
    died, a client that hung up. gmsh changes the disposition behind Python's
    back, so Python still reports the old one, and setting it again is what
    restores it. Outside the main thread Python may not set a signal; there the
    C library does it, for the one case that matters (the signal ignored).
    """
    if previous is None:
        return
    if threading.current_thread() is threading.main_thread():
        signal.signal(number, previous)
    elif previous == signal.SIG_IGN:
        import ctypes

        libc = ctypes.CDLL(None)
        libc.signal.restype = ctypes.c_void_p
        libc.signal.argtypes = [ctypes.c_int, ctypes.c_void_p]
        libc.signal(int(number), int(signal.SIG_IGN))


# ---------------------------------------------------------------------------
# building blocks
# ---------------------------------------------------------------------------
def _check_divisions(n_i, n_j):
    for name, n in (("n_i", n_i), ("n_j", n_j)):
        if int(n) != n or n < 1:
            raise ModelError(f"grid: {name} (number of divisions) must be a positive integer, got {n}")
    return int(n_i), int(n_j)


def _mesh_four_sided(gmsh, surface, curves, corner_points, n_i, n_j, dim_kernel):
    """Transfinite structured quad mesh of a four-sided surface.

    ``curves`` are the four boundary curves south, east, north, west (any
    orientation); south/north get ``n_i + 1`` nodes, east/west ``n_j + 1``.
    """
    kernel = gmsh.model.geo if dim_kernel == "geo" else gmsh.model.occ
    kernel.synchronize()
    for c, n in zip(curves, (n_i, n_j, n_i, n_j)):
        gmsh.model.mesh.setTransfiniteCurve(abs(c), n + 1)
    gmsh.model.mesh.setTransfiniteSurface(surface, "Left", corner_points)
    gmsh.model.mesh.setRecombine(2, surface)
    gmsh.option.setNumber("Mesh.RecombineAll", 1)
    gmsh.model.mesh.generate(2)


def _extract(gmsh, side_curves, corner_points) -> QuadGrid:
    """Nodes, quads and named sets of the meshed model."""
    tags, coords, _ = gmsh.model.mesh.getNodes()
    order = np.argsort(tags)
    tags = tags[order]
    nodes = coords.reshape(-1, 3)[order]
    lookup = np.full(int(tags.max()) + 1, -1, dtype=np.int64)
    lookup[tags.astype(np.int64)] = np.arange(len(tags))

    etypes, _, enodes = gmsh.model.mesh.getElements(2)
    quads = None
    for et, en in zip(etypes, enodes):
        if et == 3:  # 4-node quadrangle
            quads = lookup[np.asarray(en, dtype=np.int64)].reshape(-1, 4)
        elif et in (2, 9, 10, 16):
            raise ModelError("grid: gmsh produced non-quadrilateral elements; the surface is not four-sided")
    if quads is None or len(quads) == 0:
        raise ModelError("grid: gmsh produced no quadrangles")
    # drop nodes no quad uses (geometry points such as an arc centre)
    used = np.zeros(len(nodes), dtype=bool)
    used[quads.ravel()] = True
    renum = np.cumsum(used) - 1
    nodes = nodes[used]
    quads = renum[quads]
    lookup = np.where(lookup >= 0, renum[np.maximum(lookup, 0)], -1)

    def curve_nodes(c):
        t, _, _ = gmsh.model.mesh.getNodes(1, abs(c), includeBoundary=True)
        return lookup[t.astype(np.int64)]

    def point_node(p):
        t, _, _ = gmsh.model.mesh.getNodes(0, p)
        return int(lookup[int(t[0])])

    corners = [point_node(p) for p in corner_points]
    sides = [curve_nodes(c) for c in side_curves]
    return _structure(nodes, quads, corners, sides)


def _structure(nodes, quads, corners, sides) -> QuadGrid:
    """Structured indices from the quad topology, starting at the south-west corner."""
    n = len(nodes)
    edges = np.sort(np.concatenate([quads[:, [0, 1]], quads[:, [1, 2]], quads[:, [2, 3]], quads[:, [3, 0]]]), axis=1)
    edges = np.unique(edges, axis=0)
    # neighbour table (a structured grid node has at most 4 neighbours)
    nbr = np.full((n, 4), -1, dtype=np.int64)
    both = np.concatenate([edges, edges[:, ::-1]])
    both = both[np.argsort(both[:, 0], kind="stable")]
    start = np.searchsorted(both[:, 0], np.arange(n))
    slot = np.arange(len(both)) - start[both[:, 0]]
    if np.any(slot >= 4):
        raise ModelError("grid: a node has more than four neighbours; the mesh is not a structured quad grid")
    nbr[both[:, 0], slot] = both[:, 1]

    sw, se, ne, nw = corners
    south = _order_side(sides[0], sw, se, nbr)
    west = _order_side(sides[3], sw, nw, nbr)
    ni, nj = len(south), len(west)
    if ni * nj != n:
        raise ModelError(f"grid: {n} nodes do not form a structured {ni} x {nj} grid")
    index = np.full((ni, nj), -1, dtype=np.int64)
    index[:, 0] = south
    # walk north row by row: the next node of (i, j) is its neighbour that is not
    # (i +- 1, j) and not (i, j - 1)
    for j in range(1, nj):
        row = index[:, j - 1]
        prev = index[:, j - 2] if j >= 2 else np.full(ni, -2)
        left = np.concatenate([[-2], row[:-1]])
        right = np.concatenate([row[1:], [-2]])
        cand = nbr[row]
        bad = (cand < 0) | (cand == prev[:, None]) | (cand == left[:, None]) | (cand == right[:, None])
        cand = np.where(bad, -1, cand)
        if np.any(np.sum(cand >= 0, axis=1) != 1):
            raise ModelError("grid: could not walk the quad grid row by row; the mesh is not structured")
        index[:, j] = cand.max(axis=1)
    if index[0, -1] != nw or index[-1, -1] != ne or len(np.unique(index)) != n:
        raise ModelError("grid: the structured walk did not end at the north corners")
    ij = np.zeros((n, 2), dtype=np.int64)
    I, J = np.meshgrid(np.arange(ni), np.arange(nj), indexing="ij")
    ij[index.ravel()] = np.column_stack([I.ravel(), J.ravel()])
    groups = {
        "south": index[:, 0].copy(), "north": index[:, -1].copy(),
        "west": index[0, :].copy(), "east": index[-1, :].copy(),
        "sw": np.array([sw]), "se": np.array([se]), "ne": np.array([ne]), "nw": np.array([nw]),
        "corners": np.array([sw, se, ne, nw]),
    }
    groups["boundary"] = np.unique(np.concatenate([groups[s] for s in SIDES]))
    # orient quads counter-clockwise in (i, j)
    a, b, d = ij[quads[:, 0]], ij[quads[:, 1]], ij[quads[:, 3]]
    cross = (b[:, 0] - a[:, 0]) * (d[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (d[:, 0] - a[:, 0])
    quads = np.where(cross[:, None] < 0, quads[:, ::-1], quads)
    return QuadGrid(nodes=nodes, quads=quads, edges=edges, ij=ij, shape=(ni, nj), groups=groups)


def _order_side(side_nodes, start, end, nbr):
    """Nodes of one side ordered from ``start`` to ``end`` by walking neighbours on the side."""
    on_side = set(int(x) for x in side_nodes)
    order = [int(start)]
    prev = -1
    while order[-1] != end:
        nxt = [int(c) for c in nbr[order[-1]] if c >= 0 and c != prev and int(c) in on_side]
        if not nxt:
            raise ModelError("grid: a boundary side is not a connected line of nodes")
        prev = order[-1]
        order.append(nxt[0])
        if len(order) > len(on_side):
            raise ModelError("grid: walking a boundary side did not reach its end corner")
    return np.array(order, dtype=np.int64)


# ---------------------------------------------------------------------------
# generators
# ---------------------------------------------------------------------------
def rectangle_grid(length_x: float, length_y: float, n_i: int, n_j: int, origin=(0.0, 0.0, 0.0)) -> QuadGrid:
    """Structured grid of ``n_i x n_j`` quads on a rectangle in the plane ``z = origin[2]``.

    ``i`` runs along ``x`` (south side ``y = origin[1]``), ``j`` along ``y``.
    """
    n_i, n_j = _check_divisions(n_i, n_j)
    if not (length_x > 0 and length_y > 0):
        raise ModelError(f"rectangle grid: side lengths must be positive, got {length_x} x {length_y}")
    x0, y0, z0 = (float(c) for c in origin)
    with gmsh_session("rectangle") as gmsh:
        g = gmsh.model.geo
        p = [g.addPoint(x0, y0, z0), g.addPoint(x0 + length_x, y0, z0),
             g.addPoint(x0 + length_x, y0 + length_y, z0), g.addPoint(x0, y0 + length_y, z0)]
        c = [g.addLine(p[0], p[1]), g.addLine(p[1], p[2]), g.addLine(p[2], p[3]), g.addLine(p[3], p[0])]
        s = g.addPlaneSurface([g.addCurveLoop(c)])
        _mesh_four_sided(gmsh, s, c, p, n_i, n_j, "geo")
        grid = _extract(gmsh, c, p)
    return grid


def ellipse_grid(a: float, b: float, n: int, center=(0.0, 0.0, 0.0)) -> QuadGrid:
    """Structured ``n x n`` quad grid on an ellipse with semi-axes ``a`` (x) and ``b`` (y).

    The boundary is split into four arcs at polar angles -135, -45, 45 and
    135 degrees (south, east, north, west sides); the transfinite map fills
    the disc with two families of grid lines that both end on the rim, the
    layout of a circular gridshell. ``a == b`` gives a circle.
    """
    n, _ = _check_divisions(n, n)
    if not (a > 0 and b > 0):
        raise ModelError(f"ellipse grid: semi-axes must be positive, got {a}, {b}")
    cx, cy, cz = (float(c) for c in center)
    angles = np.deg2rad([-135.0, -45.0, 45.0, 135.0])
    corners = np.column_stack([cx + a * np.cos(angles), cy + b * np.sin(angles), np.full(4, cz)])
    with gmsh_session("ellipse") as gmsh:
        occ = gmsh.model.occ
        r1, r2 = max(a, b), min(a, b)
        # OpenCASCADE ellipses have their major axis along x; for b > a the arcs are
        # drawn in a frame turned by 90 degrees and rotated back
        shift = 0.0 if a >= b else -np.pi / 2
        arcs = []
        for k in range(4):
            t0, t1 = angles[k] + shift, angles[(k + 1) % 4] + shift
            if t1 <= t0:
                t1 += 2 * np.pi
            if a == b:
                arcs.append(occ.addCircle(cx, cy, cz, a, angle1=t0, angle2=t1))
            else:
                arcs.append(occ.addEllipse(cx, cy, cz, r1, r2, angle1=t0, angle2=t1))
        if a < b:
            occ.rotate([(1, c) for c in arcs], cx, cy, cz, 0, 0, 1, np.pi / 2)
        surf = occ.addPlaneSurface([occ.addCurveLoop(arcs)])
        occ.synchronize()
        side_curves, corner_pts = _four_sides(gmsh, surf, corners)
        _mesh_four_sided(gmsh, surf, side_curves, corner_pts, n, n, "occ")
        grid = _extract(gmsh, side_curves, corner_pts)
    return grid


def disk_grid(radius: float, n: int, center=(0.0, 0.0, 0.0)) -> QuadGrid:
    """Structured ``n x n`` quad grid on a circle (see :func:`ellipse_grid`)."""
    return ellipse_grid(radius, radius, n, center)


def bspline_surface_grid(surface, n_i: int, n_j: int) -> QuadGrid:
    """Structured quad grid on a B-spline/NURBS surface (gmsh OpenCASCADE kernel).

    Parameters
    ----------
    surface : BSplineSurface
        Control net ``(nu, nv, 3)``, degrees, knots and weights. The grid's
        ``i`` direction follows ``u`` and ``j`` follows ``v``; the south side
        is ``v = 0``.
    n_i, n_j : int
        Quads along ``u`` and ``v``.
    """
    n_i, n_j = _check_divisions(n_i, n_j)
    P = surface.control_points
    nu, nv = P.shape[:2]
    knots_u, mult_u = _knots_and_multiplicities(surface.knots_u)
    knots_v, mult_v = _knots_and_multiplicities(surface.knots_v)
    with gmsh_session("bspline") as gmsh:
        occ = gmsh.model.occ
        # OpenCASCADE numbers the poles with u running fastest
        tags = [occ.addPoint(*P[i, j]) for j in range(nv) for i in range(nu)]
        w = [float(surface.weights[i, j]) for j in range(nv) for i in range(nu)]
        s = occ.addBSplineSurface(tags, nu, degreeU=surface.degree_u, degreeV=surface.degree_v, weights=w,
                                  knotsU=knots_u, knotsV=knots_v, multiplicitiesU=mult_u,
                                  multiplicitiesV=mult_v)
        occ.remove([(0, t) for t in tags])
        occ.synchronize()
        side_curves, corner_pts = _four_sides(gmsh, s, [P[0, 0], P[-1, 0], P[-1, -1], P[0, -1]])
        _mesh_four_sided(gmsh, s, side_curves, corner_pts, n_i, n_j, "occ")
        grid = _extract(gmsh, side_curves, corner_pts)
    return grid


def _four_sides(gmsh, surface, corner_targets):
    """Boundary curves (south, east, north, west) and corner points (sw, se, ne, nw)
    of an OpenCASCADE surface, matched to the expected corner coordinates."""
    curves = [c for _, c in gmsh.model.getBoundary([(2, surface)], oriented=False)]
    points = {p for _, p in gmsh.model.getBoundary([(2, surface)], combined=False, oriented=False, recursive=True)}
    xyz = {p: np.array(gmsh.model.getValue(0, p, [])) for p in points}
    corner_pts = [min(xyz, key=lambda p, t=t: np.linalg.norm(xyz[p] - np.asarray(t))) for t in corner_targets]
    if len(set(corner_pts)) != 4 or len(curves) != 4:
        raise ModelError("grid: the surface does not have four distinct corners and four sides")
    side = {}
    for c in curves:
        ends = [p for _, p in gmsh.model.getBoundary([(1, c)], oriented=False)]
        side[frozenset(ends)] = c
    try:
        side_curves = [side[frozenset((corner_pts[i], corner_pts[(i + 1) % 4]))] for i in range(4)]
    except KeyError:
        raise ModelError("grid: the surface sides do not join its corners in order") from None
    return side_curves, corner_pts


def _knots_and_multiplicities(knots):
    k = np.asarray(knots, dtype=float)
    values, counts = np.unique(k, return_counts=True)
    return [float(v) for v in values], [int(c) for c in counts]
