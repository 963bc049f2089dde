"""The Gridshell component on given lines: a rod along every curve, joined where the curves meet.

Every curve is one rod through its points (:func:`~shellform.hops.nets.centreline`:
a line's ends, a polyline's vertices, a smooth curve divided into segments);
points of different curves closer than a tolerance relative to the model's
size are one node, a joint the rods share
(:func:`shellform.rods.stack_polylines`). The model is the rod scene of
those nodes and ``[[rods.lines]]`` (``shellform.scene.rod_layouts``), traced
under its weight by arc-length continuation to its first critical point.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .component import JOIN_TOLERANCE, Built, nearest_nodes
from .nets import centreline
from ..errors import ShellformError
from .protocol import InputError

#: a smooth curve is divided into segments of the model's size over this, unless SegmentLength says
SEGMENTS_PER_SIZE = 20
#: a support point or curve takes the nodes within this fraction of the shortest rod edge
SUPPORT_REACH = 0.25
#: samples of a smooth curve to find the model's size before it is divided
_SIZE_SAMPLES = 33
#: inputs that shape a net to be found, none of which a gridshell of given lines has
_NET_ONLY = ("Holes", "EdgeLength", "DivisionsY")


@dataclass(frozen=True)
class RodLines:
    """The rods of given curves.

    Attributes
    ----------
    nodes : ndarray (n, 3)
    chains : list of ndarray
        Node numbers along every rod, in the order of the curves.
    closed : list of bool
        Whether each rod is a ring (a closed curve).
    spacing : float
        The shortest rod edge [m].
    tolerance : float
        Points closer than this [m] are one node.
    """

    nodes: np.ndarray
    chains: list
    closed: list
    spacing: float
    tolerance: float

    def rod_ends(self) -> np.ndarray:
        """The nodes where a rod ends (the set 'boundary'): the edge of a gridshell of laths."""
        ends = [c[[0, -1]] for c, cl in zip(self.chains, self.closed) if not cl]
        return np.unique(np.concatenate(ends)) if ends else np.zeros(0, dtype=np.int64)


def _edges(chain: np.ndarray, closed: bool) -> np.ndarray:
    nxt = np.roll(chain, -1) if closed else chain[1:]
    return np.column_stack([chain[: len(nxt)], nxt])


def rod_lines(curves: list, segment_length: float | None) -> RodLines:
    """The rods of the Lines input: one per curve, joined where their points meet."""
    from ..rods import stack_polylines

    if len(curves) < 2:
        raise InputError("Lines", f"got {len(curves)} curve; a gridshell needs at least two rods that meet")
    size = _size(curves)
    if not size > 0:
        raise InputError("Lines", "has no extent: all its points are at one point")
    tolerance = JOIN_TOLERANCE * size
    if segment_length is None:
        segment_length = size / SEGMENTS_PER_SIZE
    elif isinstance(segment_length, bool) or not isinstance(segment_length, (int, float)) or not segment_length > 0:
        raise InputError("SegmentLength", f"got {segment_length!r}; expected a length > 0")
    polylines, closed = [], []
    for k, curve in enumerate(curves):
        pts, ring = _rod_points(curve, k, float(segment_length), tolerance)
        polylines.append(pts)
        closed.append(ring)
    # points of different curves within the tolerance share a node, a joint (stack_polylines takes the tolerance
    # relative to the largest side of the points' box)
    side = max(float(np.ptp(np.concatenate(polylines), axis=0).max()), 1e-300)
    nodes, chains, _ = stack_polylines(polylines, merge=True, tol=tolerance / side)
    for k, chain in enumerate(chains):
        if np.any(chain[1:] == chain[:-1]):
            raise InputError("Lines", f"item {k} passes one joint twice in a row (it touches another curve twice "
                             f"within {tolerance:.3g} m)")
    edges = np.concatenate([_edges(c, cl) for c, cl in zip(chains, closed)])
    spacing = float(np.linalg.norm(nodes[edges[:, 0]] - nodes[edges[:, 1]], axis=1).min())
    lines = RodLines(nodes, chains, closed, spacing, tolerance)
    _check_connected(lines, edges)
    return lines


def _size(curves: list) -> float:
    """The diagonal of the box of all curves [m] (smooth curves sampled)."""
    pts = []
    for k, curve in enumerate(curves):
        if isinstance(curve, list):
            pts.append(centreline(curve, 1.0, f"Lines[{k}]"))
        elif hasattr(curve, "PointAt"):
            d = curve.Domain
            pts.append(np.array([[p.X, p.Y, p.Z] for p in (curve.PointAt(float(t)) for t in
                                                           np.linspace(d.T0, d.T1, _SIZE_SAMPLES))]))
        else:
            raise InputError("Lines", f"item {k} is a {type(curve).__name__}, not a curve")
    pts = np.concatenate(pts)
    if not np.all(np.isfinite(pts)):
        raise InputError("Lines", "has a point with a coordinate that is not a finite number")
    return float(np.linalg.norm(np.ptp(pts, axis=0)))


def _rod_points(curve, k: int, segment_length: float, tolerance: float) -> tuple[np.ndarray, bool]:
    """The points of one rod and whether it is a ring; a curve of zero length, or with a segment of zero length,
    is refused."""
    pts = centreline(curve, segment_length, f"Lines[{k}]")
    step = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    if step.sum() <= tolerance:
        raise InputError("Lines", f"item {k} has zero length")
    ring = len(pts) >= 4 and np.linalg.norm(pts[-1] - pts[0]) <= tolerance
    if ring:
        pts, step = pts[:-1], step[:-1]
    short = np.flatnonzero(step <= tolerance)
    if short.size:
        i = int(short[0])
        raise InputError("Lines", f"item {k} has a segment of zero length (between its points {i} and {i + 1})")
    return pts, bool(ring)


def _check_connected(lines: RodLines, edges: np.ndarray) -> None:
    """All rods must make one structure: joined, directly or through others, where their points meet."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    n = len(lines.nodes)
    graph = coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(n, n))
    parts, label = connected_components(graph, directed=False)
    if parts > 1:
        first = label[lines.chains[0][0]]
        k = next(i for i, c in enumerate(lines.chains) if label[c[0]] != first)
        raise InputError("Lines", f"the curves are not connected into one structure: {parts} separate parts "
                         f"(item {k} is not joined to item 0); curves are joined where their points (ends, "
                         f"vertices, division points) meet, within {lines.tolerance:.3g} m")


# -- supports -------------------------------------------------------------------------------------


def lines_supports(v: dict, lines: RodLines) -> np.ndarray:
    """The supported nodes: the named set 'boundary' (the free ends), nodes at points and on curves."""
    from ..geometry.selection import nodes_on_polyline

    reach = SUPPORT_REACH * lines.spacing
    chosen = []
    groups = v["Supports"]
    for g in [s.strip() for s in groups.split(",") if s.strip()] if isinstance(groups, str) else []:
        if g != "boundary":
            raise InputError("Supports", f"lines have no node set {g!r}; their set: 'boundary' (the ends of the "
                             "rods)")
        chosen.append(lines.rod_ends())
    if v["SupportPoints"]:
        chosen.append(np.array(nearest_nodes(lines.nodes, v["SupportPoints"], reach, "SupportPoints")))
    for k, curve in enumerate(v["SupportCurves"] or []):
        pts = centreline(curve, reach, f"SupportCurves[{k}]")
        on = nodes_on_polyline(lines.nodes, pts, reach)
        if not on.size:
            raise InputError("SupportCurves", f"item {k} passes no node of the rods (within {reach:.3g} m)")
        chosen.append(on)
    nodes = np.unique(np.concatenate(chosen)) if chosen else np.zeros(0, dtype=np.int64)
    if not nodes.size:
        raise InputError("Supports", "the gridshell needs supports: give 'boundary' (the ends of the rods), "
                         "SupportPoints or SupportCurves")
    _check_not_on_a_line(lines, nodes)
    return nodes


def _check_not_on_a_line(lines: RodLines, nodes: np.ndarray) -> None:
    """Pinned nodes all on one line leave the gridshell free to turn about it: a mechanism."""
    x = lines.nodes[nodes]
    spread = np.linalg.svd(x - x.mean(axis=0), compute_uv=False) if len(x) > 1 else np.zeros(1)
    if len(spread) < 2 or spread[1] <= lines.tolerance:
        where = "one node" if len(x) == 1 else f"{len(x)} nodes on one line"
        raise InputError("Supports", f"the supports are {where}: the gridshell can turn about them (a mechanism); "
                         "support at least three nodes that are not on one line")


# -- the scene ------------------------------------------------------------------------------------


def lines_scene(v: dict) -> Built:
    """The rod scene of the Gridshell inputs on given Lines: continuation of its weight to buckling."""
    for name in _NET_ONLY:
        if v[name] is not None:
            raise InputError(name, "applies to a Boundary outline; Lines are the rods as given")
    lines = rod_lines(v["Lines"], v["SegmentLength"])
    supported = lines_supports(v, lines)
    rods = {**section_keys(v), "E": v["E"], "G": v["G"], "density": _density(v), "rest_shape": v["RestShape"],
            "joints": v["Joints"], "joint_rotational_stiffness": v["JointStiffness"],
            "lines": [{"nodes": c.tolist(), "closed": cl} for c, cl in zip(lines.chains, lines.closed)]}
    scene = {
        "title": "from Grasshopper",
        "nodes": {"coordinates": lines.nodes.tolist()},
        "rods": rods,
        "masses": {"node_mass": v["NodeMass"]},
        "supports": [{"nodes": supported.tolist()}],
        "gravity": {"scaled": True},
        "analysis": {"type": "continuation", "continuation": {
            "control": "load", "parameter_max": v["LoadFactorMax"], "max_steps": v["MaxSteps"],
            "on_bifurcation": "stop"}},
    }
    keys = {"nodes": "Lines", "rods.lines": "Lines", "rods": "Lines", "supports": "Supports",
            "masses.node_mass": "NodeMass", "analysis.continuation.parameter_max": "LoadFactorMax",
            "analysis.continuation.max_steps": "MaxSteps", "rods.radius": "Radius", "rods.section": "Section",
            "rods.thickness": "Thickness", "rods.depth": "Depth", "rods.width": "Width", "rods.E": "E", "rods.G": "G",
            "rods.density": "Density", "rods.rest_shape": "RestShape", "rods.joints": "Joints",
            "rods.joint_rotational_stiffness": "JointStiffness"}
    return Built(scene, keys, {"lines": lines})


def section_keys(v: dict) -> dict:
    """The scene keys of the section inputs: a rectangle has no radius (Radius has a default), the others only
    what is given, so that the scene's checks name a dimension that does not apply."""
    keys = {"section": v["Section"], "thickness": v["Thickness"], "depth": v["Depth"], "width": v["Width"]}
    if v["Section"] != "rectangle":
        keys["radius"] = v["Radius"]
    return {k: x for k, x in keys.items() if x is not None}


def _density(v: dict):
    """The rods' density with MassPerLength spread over their section: their weight per metre besides Density's."""
    from ..geometry.sections import hollow_circle, rectangle, solid_circle

    rho, mass = v["Density"], v["MassPerLength"]
    if not (isinstance(mass, (int, float)) and not isinstance(mass, bool) and mass > 0):
        return rho
    try:
        shape = {"circle": lambda: solid_circle(v["Radius"]),
                 "hollow_circle": lambda: hollow_circle(v["Radius"], v["Thickness"]),
                 "rectangle": lambda: rectangle(v["Depth"], v["Width"])}[v["Section"]]()
    except (KeyError, TypeError, ValueError, ShellformError):
        return rho  # the scene's check names what is wrong with the section
    return rho + mass / shape.area
