"""Planforms of any shape meshed by gmsh: polygons with holes, B-spline/NURBS boundaries, imported surfaces.

Each generator builds the surface in gmsh and meshes it with a target edge
length, as quads or as triangles:

* quads on a single four-sided patch without holes (a four-cornered polygon,
  four boundary curves) are transfinite, so the result is a structured
  :class:`~shellform.geometry.grids.QuadGrid` with its grid lines;
* quads elsewhere are recombined from an unstructured mesh (gmsh's
  Frontal-Delaunay for quads and Blossom recombination), triangles are
  Frontal-Delaunay; both give a :class:`~shellform.geometry.meshnet.MeshNet`.

Named node sets of a gmsh planform: ``"boundary"``, ``"corners"`` (the
geometry's points on the boundary), ``"outer"`` (the outer loop),
``"hole_1"``, ``"hole_2"``, ... (each hole's loop) and ``"side_0"``,
``"side_1"``, ... (the nodes of each segment or curve of the outer loop, in
order; ``"hole_1_side_0"``, ... for the holes). An imported surface has
``"boundary"``, ``"corners"`` and ``"curve_<tag>"`` for each of its
boundary curves.

STEP, IGES and BREP files are read by gmsh's OpenCASCADE kernel
(:func:`surface_planform`), which the gmsh wheels on PyPI include.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import ModelError
from .grids import QuadGrid, _extract, _mesh_four_sided, gmsh_session
from .meshnet import MeshNet

ELEMENTS = ("quads", "triangles")
#: file extensions of the surfaces gmsh's OpenCASCADE kernel imports
SURFACE_FILES = (".step", ".stp", ".iges", ".igs", ".brep")
#: most nodes a planform may have (about edge_length^-2 times its area): a unit off is caught before meshing
MAX_PLANFORM_NODES = 2_000_000


@dataclass(frozen=True)
class BoundaryCurve:
    """A B-spline or NURBS curve of a planform's boundary (clamped uniform knots).

    Attributes
    ----------
    control_points : ndarray, shape (k, 3)
    degree : int
    weights : ndarray, shape (k,), optional
        NURBS weights (default all 1).
    """

    control_points: np.ndarray
    degree: int = 3
    weights: np.ndarray | None = None


def _check_mesh_options(edge_length: float, elements: str) -> None:
    if not (np.isfinite(edge_length) and edge_length > 0):
        raise ModelError(f"planform: edge_length must be a positive number, got {edge_length!r}")
    if elements not in ELEMENTS:
        raise ModelError(f"planform: elements must be one of {ELEMENTS}, got {elements!r}")


def _loop_points(points, what: str) -> np.ndarray:
    """A closed polyline's distinct corners, (k, 3) (a repeated first point at the end is dropped)."""
    p = np.asarray(points, dtype=float)
    if p.ndim != 2 or p.shape[1] not in (2, 3):
        raise ModelError(f"{what}: expected a list of [x, y] or [x, y, z] points, got shape {p.shape}")
    if p.shape[1] == 2:
        p = np.column_stack([p, np.zeros(len(p))])
    if len(p) > 1 and np.allclose(p[0], p[-1]):
        p = p[:-1]
    if len(p) < 3:
        raise ModelError(f"{what}: a closed polyline needs at least 3 distinct points, got {len(p)}")
    if not np.all(np.isfinite(p)):
        raise ModelError(f"{what}: coordinates must be finite")
    seg = np.linalg.norm(np.roll(p, -1, axis=0) - p, axis=1)
    if np.any(seg <= 1e-12 * max(float(np.ptp(p, axis=0).max()), 1.0)):
        k = int(np.argmin(seg))
        raise ModelError(f"{what}: points {k} and {(k + 1) % len(p)} coincide")
    return p


def _check_size(area: float, edge_length: float) -> None:
    n = area / edge_length / edge_length  # not edge_length**2: that underflows to 0 for a tiny length
    if n > MAX_PLANFORM_NODES:
        raise ModelError(f"planform: edge_length {edge_length:g} m would give about {n:,.0f} nodes on "
                         f"{area:.4g} m^2; at most {MAX_PLANFORM_NODES:,} are allowed")


def _polygon_area(p: np.ndarray) -> float:
    n = np.cross(p - p[0], np.roll(p, -1, axis=0) - p[0]).sum(axis=0)
    return 0.5 * float(np.linalg.norm(n))


def _in_plane(loops: list[np.ndarray]) -> list[np.ndarray]:
    """The loops in 2-D coordinates of the outer loop's plane; refused when they leave that plane."""
    outer = loops[0]
    span = float(np.ptp(np.concatenate(loops), axis=0).max())
    # the plane that fits the boundary's corners best (its normal: the direction of least spread)
    _, sv, axes = np.linalg.svd(outer - outer.mean(axis=0))
    if len(sv) < 2 or sv[1] <= 1e-9 * max(sv[0], 1e-300):
        raise ModelError("planform boundary: its corners lie on one line; they enclose no area")
    e1, e2, normal = axes[0], axes[1], np.cross(axes[0], axes[1])
    for k, p in enumerate(loops):
        off = np.abs((p - outer[0]) @ normal).max()
        if off > 1e-9 * span:
            what = "planform boundary" if k == 0 else f"planform hole {k}"
            raise ModelError(f"{what}: a corner lies {off:.3g} m off the plane of the boundary; the loops must lie "
                             "in one plane")
    return [np.stack([(p - outer[0]) @ e1, (p - outer[0]) @ e2], axis=1) for p in loops]


def _crossing(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Which segments of the closed loop ``a`` meet which of ``b`` (touching counts), shape (len(a), len(b))."""
    a1, a2 = a, np.roll(a, -1, axis=0)
    b1, b2 = b, np.roll(b, -1, axis=0)

    def orient(p, q, r):  # sign of the turn p -> q -> r, for all pairs
        return np.sign((q[:, None, 0] - p[:, None, 0]) * (r[None, :, 1] - p[:, None, 1])
                       - (q[:, None, 1] - p[:, None, 1]) * (r[None, :, 0] - p[:, None, 0]))

    d1, d2 = orient(a1, a2, b1), orient(a1, a2, b2)
    d3 = orient(b1, b2, a1).T
    d4 = orient(b1, b2, a2).T
    proper = (d1 * d2 < 0) & (d3 * d4 < 0)
    # a collinear end point touches the other segment only where it lies within it
    lo_a, hi_a = np.minimum(a1, a2), np.maximum(a1, a2)
    lo_b, hi_b = np.minimum(b1, b2), np.maximum(b1, b2)
    b1_on_a = np.all((lo_a[:, None] <= b1[None]) & (b1[None] <= hi_a[:, None]), axis=2)
    b2_on_a = np.all((lo_a[:, None] <= b2[None]) & (b2[None] <= hi_a[:, None]), axis=2)
    a1_on_b = np.all((lo_b[None] <= a1[:, None]) & (a1[:, None] <= hi_b[None]), axis=2)
    a2_on_b = np.all((lo_b[None] <= a2[:, None]) & (a2[:, None] <= hi_b[None]), axis=2)
    touching = ((d1 == 0) & b1_on_a) | ((d2 == 0) & b2_on_a) | ((d3 == 0) & a1_on_b) | ((d4 == 0) & a2_on_b)
    return proper | touching


def _inside(points: np.ndarray, loop: np.ndarray) -> np.ndarray:
    """Even-odd rule: which points lie inside the closed loop."""
    x, y = points[:, None, 0], points[:, None, 1]
    x1, y1 = loop[None, :, 0], loop[None, :, 1]
    x2, y2 = np.roll(loop, -1, axis=0)[None, :, 0], np.roll(loop, -1, axis=0)[None, :, 1]
    up = (y1 > y) != (y2 > y)
    with np.errstate(divide="ignore", invalid="ignore"):
        xs = x1 + (y - y1) * (x2 - x1) / (y2 - y1)
    return np.count_nonzero(up & (x < xs), axis=1) % 2 == 1


def _polygon_side(n: int, a: int) -> str:
    return f"side {a} (corners {a}-{(a + 1) % n})"


def _check_loops(loops: list[np.ndarray], side=_polygon_side) -> None:
    """Loops gmsh can mesh: each simple, every hole strictly inside the boundary, holes apart.

    gmsh does not refuse a hole that crosses the boundary or a loop that
    crosses itself: it meshes for minutes or forever. ``side(n, a)`` names
    segment ``a`` of a loop of ``n`` in a message.
    """
    flat = _in_plane(loops)
    names = ["planform boundary"] + [f"planform hole {k}" for k in range(1, len(loops))]
    for name, p in zip(names, flat):
        meet = _crossing(p, p)
        n = len(p)
        i, j = np.nonzero(np.triu(meet, 2))
        bad = [(a, b) for a, b in zip(i, j) if not (a == 0 and b == n - 1)]  # neighbours share a corner
        if bad:
            a, b = bad[0]
            raise ModelError(f"{name}: {side(n, a)} meets {side(n, b)}; a loop must not cross itself")
    for k in range(1, len(flat)):
        if np.any(_crossing(flat[k], flat[0])) or not np.all(_inside(flat[k], flat[0])):
            raise ModelError(f"{names[k]}: not inside the planform boundary (it reaches or crosses it)")
        for m in range(1, k):
            if np.any(_crossing(flat[k], flat[m])) or np.any(_inside(flat[k][:1], flat[m])) \
                    or np.any(_inside(flat[m][:1], flat[k])):
                raise ModelError(f"{names[k]} and {names[m]} overlap; holes must lie apart")


def polygon_planform(boundary, holes=(), *, edge_length: float, elements: str = "quads") -> QuadGrid | MeshNet:
    """A planform bounded by a closed polyline, with polygonal holes, meshed by gmsh.

    Parameters
    ----------
    boundary : array_like, shape (k, 2) or (k, 3)
        Corners of the outer boundary in order (closing segment implied). The
        loops must lie in one plane.
    holes : sequence of array_like
        Corners of each hole.
    edge_length : float
        Target length of the mesh edges [m].
    elements : {"quads", "triangles"}

    Returns
    -------
    QuadGrid or MeshNet
        A structured grid for quads on a four-cornered polygon without holes.
    """
    _check_mesh_options(edge_length, elements)
    outer = _loop_points(boundary, "planform boundary")
    inner = [_loop_points(h, f"planform hole {k + 1}") for k, h in enumerate(holes)]
    _check_loops([outer] + inner)
    _check_size(_polygon_area(outer), edge_length)
    with gmsh_session("polygon") as gmsh:
        g = gmsh.model.geo
        loops, sides = [], []
        for p in [outer] + inner:
            pts = [g.addPoint(*x) for x in p]
            curves = [g.addLine(pts[i], pts[(i + 1) % len(pts)]) for i in range(len(pts))]
            loops.append(g.addCurveLoop(curves))
            sides.append((curves, pts))
        surface = g.addPlaneSurface(loops)
        g.synchronize()
        if elements == "quads" and len(outer) == 4 and not inner:
            curves, pts = sides[0]
            n_i, n_j = (_divisions(outer, edge_length, k) for k in (0, 1))
            _mesh_four_sided(gmsh, surface, curves, pts, n_i, n_j, "geo")
            return _extract(gmsh, curves, pts)
        return _unstructured(gmsh, edge_length, elements, _loop_groups(sides))


def _divisions(corners: np.ndarray, h: float, k: int) -> int:
    """Divisions of sides k and k + 2 of a four-cornered loop: the longer one over the edge length."""
    length = [np.linalg.norm(corners[(i + 1) % 4] - corners[i]) for i in (k, k + 2)]
    return max(1, int(round(max(length) / h)))


def curve_planform(loops, *, edge_length: float, elements: str = "quads") -> QuadGrid | MeshNet:
    """A planform bounded by B-spline/NURBS curves (gmsh's OpenCASCADE kernel).

    Parameters
    ----------
    loops : sequence of sequences of BoundaryCurve
        The outer loop first, then the holes; each loop's curves run end to
        end (the last control point of a curve is the first of the next, the
        last curve ends where the first starts; a loop of one closed curve is
        allowed). The loops must lie in one plane.
    edge_length, elements
        See :func:`polygon_planform`. A loop of four curves without holes is
        meshed transfinite as quads (a :class:`QuadGrid`).
    """
    _check_mesh_options(edge_length, elements)
    if not loops or not all(len(loop) for loop in loops):
        raise ModelError("planform curves: every loop needs at least one curve")
    polylines = [_curve_polyline(loop, k) for k, loop in enumerate(loops)]
    _check_loops(polylines, _curve_side)
    with gmsh_session("curves") as gmsh:
        occ = gmsh.model.occ
        loop_tags, sides = [], []
        for k, loop in enumerate(loops):
            curves, corners = _add_loop(occ, loop, k)
            loop_tags.append(occ.addCurveLoop(curves))
            sides.append((curves, corners))
        try:
            surface = occ.addPlaneSurface(loop_tags)
        except Exception as exc:  # gmsh raises a bare Exception
            raise ModelError(f"planform curves: gmsh could not make a plane surface of the loops ({exc})") from None
        occ.synchronize()
        area = gmsh.model.occ.getMass(2, surface)
        _check_size(area, edge_length)
        if elements == "quads" and len(loops) == 1 and len(loops[0]) == 4:
            curves, corners = sides[0]
            length = [gmsh.model.occ.getMass(1, c) for c in curves]
            n_i = max(1, int(round(max(length[0], length[2]) / edge_length)))
            n_j = max(1, int(round(max(length[1], length[3]) / edge_length)))
            _mesh_four_sided(gmsh, surface, curves, corners, n_i, n_j, "occ")
            return _extract(gmsh, curves, corners)
        return _unstructured(gmsh, edge_length, elements, _loop_groups(sides))


#: points at which each boundary curve is evaluated to check its loop before meshing (a polyline through
#: them): a crossing of two curves shows unless it is shallower than a 64th of a curve
CURVE_SAMPLES = 64


def _curve_side(n: int, a: int) -> str:
    return f"curve {a // (CURVE_SAMPLES - 1)}"


def _curve_polyline(loop, k: int) -> np.ndarray:
    """The loop's curves evaluated at CURVE_SAMPLES parameters each, end to end: (m, 3) corners of a polyline."""
    from .bspline import basis_functions, clamped_uniform_knots

    u = np.linspace(0.0, 1.0, CURVE_SAMPLES)
    out = []
    for c, P in zip(loop, _control_points(loop, k)):
        w = np.ones(len(P)) if c.weights is None else np.broadcast_to(np.asarray(c.weights, dtype=float), (len(P),))
        N = basis_functions(clamped_uniform_knots(len(P), int(c.degree)), int(c.degree), u) * w
        out.append(((N @ P) / N.sum(axis=1)[:, None])[:-1])
    return np.concatenate(out)


def _control_points(loop, k: int) -> list[np.ndarray]:
    """The control points of every curve of a loop, checked: shapes, degrees, weights, curves end to end."""
    what = "planform outer loop" if k == 0 else f"planform hole {k}"
    pts = []
    for m, c in enumerate(loop):
        P = np.asarray(c.control_points, dtype=float)
        if P.ndim != 2 or P.shape[1] != 3 or len(P) < 2:
            raise ModelError(f"{what}, curve {m}: control points must be a list of at least 2 [x, y, z] points")
        if not 1 <= int(c.degree) < len(P):
            raise ModelError(f"{what}, curve {m}: degree {c.degree} does not suit {len(P)} control points "
                             f"(expected 1..{len(P) - 1})")
        if not np.all(np.isfinite(P)):
            raise ModelError(f"{what}, curve {m}: control points must be finite")
        if c.weights is not None:
            w = np.asarray(c.weights, dtype=float)
            if w.ndim > 1 or (w.ndim == 1 and len(w) != len(P)) or not np.all(np.isfinite(w) & (w > 0)):
                raise ModelError(f"{what}, curve {m}: weights must be {len(P)} positive numbers (one per control "
                                 "point)")
        pts.append(P)
    scale = max(float(np.ptp(np.concatenate(pts), axis=0).max()), 1e-9)
    tol = 1e-9 * scale
    n = len(loop)
    for m in range(n):
        a, b = pts[m][-1], pts[(m + 1) % n][0]
        if np.linalg.norm(a - b) > tol:
            raise ModelError(f"{what}: curve {m} ends at {a.tolist()} but curve {(m + 1) % n} starts at "
                             f"{b.tolist()}; the curves of a loop must run end to end")
    return pts


def _add_loop(occ, loop, k: int):
    """The B-spline curves of one loop, sharing their end points; returns (curve tags, corner point tags)."""
    pts = _control_points(loop, k)
    n = len(loop)
    starts = [occ.addPoint(*P[0]) for P in pts]
    curves = []
    for m, (c, P) in enumerate(zip(loop, pts)):
        inner = [occ.addPoint(*x) for x in P[1:-1]]
        tags = [starts[m]] + inner + [starts[(m + 1) % n]]
        w = [] if c.weights is None else [float(x) for x in np.broadcast_to(c.weights, (len(P),))]
        curves.append(occ.addBSpline(tags, degree=int(c.degree), weights=w))
    return curves, starts


def _loop_groups(sides) -> dict:
    """Entity tags of each named node set of a gmsh planform: (dim, tag) lists by name."""
    groups = {"corners": [(0, p) for _, pts in sides for p in pts]}
    for k, (curves, _) in enumerate(sides):
        name = "outer" if k == 0 else f"hole_{k}"
        groups[name] = [(1, abs(c)) for c in curves]
        for m, c in enumerate(curves):
            groups[("side_" if k == 0 else f"hole_{k}_side_") + str(m)] = [(1, abs(c))]
    return groups


def surface_planform(path, *, edge_length: float, elements: str = "quads") -> QuadGrid | MeshNet:
    """The surfaces of a STEP, IGES or BREP file meshed by gmsh's OpenCASCADE kernel.

    A file of one four-sided face is meshed transfinite as quads (a
    :class:`QuadGrid`); otherwise every face is meshed unstructured and the
    faces share the nodes of their common curves.
    """
    _check_mesh_options(edge_length, elements)
    path = Path(path)
    if path.suffix.lower() not in SURFACE_FILES:
        raise ModelError(f"surface file {str(path)!r}: expected one of {', '.join(SURFACE_FILES)}")
    if not path.is_file():
        raise ModelError(f"surface file {str(path)!r} does not exist or is not a file")
    with gmsh_session("surface") as gmsh:
        occ = gmsh.model.occ
        try:
            shapes = occ.importShapes(str(path))
        except Exception as exc:
            raise ModelError(f"surface file {str(path)!r}: gmsh could not read it ({exc})") from None
        occ.synchronize()
        faces = [t for d, t in gmsh.model.getEntities(2)]
        if not faces:
            raise ModelError(f"surface file {str(path)!r} holds no surface ({len(shapes)} shapes of lower dimension)")
        if len(faces) > 1:
            occ.fragment([(2, f) for f in faces[:1]], [(2, f) for f in faces[1:]])  # shared curves, shared nodes
            occ.synchronize()
            faces = [t for d, t in gmsh.model.getEntities(2)]
        _check_size(sum(occ.getMass(2, f) for f in faces), edge_length)
        boundary = gmsh.model.getBoundary([(2, f) for f in faces], combined=True, oriented=False)
        curves = sorted({abs(t) for _, t in boundary})
        points = {p for _, p in gmsh.model.getBoundary([(1, c) for c in curves], combined=False, oriented=False)}
        if elements == "quads" and len(faces) == 1 and len(curves) == 4 and len(points) == 4:
            side_curves, corner_pts = _cycle_of_curves(gmsh, curves)
            length = [occ.getMass(1, c) for c in side_curves]
            n_i = max(1, int(round(max(length[0], length[2]) / edge_length)))
            n_j = max(1, int(round(max(length[1], length[3]) / edge_length)))
            _mesh_four_sided(gmsh, faces[0], side_curves, corner_pts, n_i, n_j, "occ")
            return _extract(gmsh, side_curves, corner_pts)
        groups = {"corners": [(0, p) for p in sorted(points)], **{f"curve_{c}": [(1, c)] for c in curves}}
        return _unstructured(gmsh, edge_length, elements, groups)


def _cycle_of_curves(gmsh, curves):
    """Four boundary curves in order around their face, and the corners between them (curve k from corner k)."""
    ends = {c: [p for _, p in gmsh.model.getBoundary([(1, c)], oriented=False)] for c in curves}
    order, corners = [curves[0]], [ends[curves[0]][0]]
    at = ends[curves[0]][1]
    while len(order) < 4:
        nxt = [c for c in curves if c not in order and at in ends[c]]
        if not nxt:
            raise ModelError("surface: the four boundary curves of the face do not form one loop")
        corners.append(at)
        order.append(nxt[0])
        at = [p for p in ends[nxt[0]] if p != at][0]
    return order, corners


def _unstructured(gmsh, edge_length: float, elements: str, groups: dict) -> MeshNet:
    """Mesh every surface of the model unstructured and extract the net with its named node sets."""
    opt = gmsh.option.setNumber
    opt("Mesh.MeshSizeMin", edge_length)
    opt("Mesh.MeshSizeMax", edge_length)
    opt("Mesh.MeshSizeFromPoints", 0)
    opt("Mesh.MeshSizeExtendFromBoundary", 0)
    opt("Mesh.MeshSizeFromCurvature", 0)
    opt("Mesh.Algorithm", 8 if elements == "quads" else 6)  # Frontal-Delaunay (for quads)
    if elements == "quads":
        opt("Mesh.RecombinationAlgorithm", 1)  # Blossom
        opt("Mesh.RecombineAll", 1)
    gmsh.model.mesh.generate(2)
    tags, coords, _ = gmsh.model.mesh.getNodes()
    order = np.argsort(tags)
    tags, nodes = tags[order].astype(np.int64), coords.reshape(-1, 3)[order]
    lookup = np.full(int(tags.max()) + 1, -1, dtype=np.int64)
    lookup[tags] = np.arange(len(tags))
    cells = {2: [], 3: []}
    for et, en in zip(*gmsh.model.mesh.getElements(2)[::2]):
        if int(et) not in cells:
            raise ModelError(f"planform: gmsh produced elements of type {int(et)}, not linear triangles or quads")
        cells[int(et)].append(lookup[np.asarray(en, dtype=np.int64)].reshape(-1, 3 if et == 2 else 4))
    tri = np.concatenate(cells[2]) if cells[2] else np.zeros((0, 3), dtype=np.int64)
    quad = np.concatenate(cells[3]) if cells[3] else np.zeros((0, 4), dtype=np.int64)
    used = np.zeros(len(nodes), dtype=bool)
    used[tri.ravel()] = True
    used[quad.ravel()] = True
    renum = np.cumsum(used) - 1
    named = {}
    for name, entities in groups.items():
        parts = []
        for dim, tag in entities:
            t, _, _ = gmsh.model.mesh.getNodes(dim, tag, includeBoundary=True)
            parts.append(lookup[t.astype(np.int64)])
        ids = np.concatenate(parts) if parts else np.zeros(0, dtype=np.int64)
        named[name] = renum[ids[(ids >= 0) & used[np.maximum(ids, 0)]]]
    return MeshNet(nodes[used], renum[quad], renum[tri], groups=named)
