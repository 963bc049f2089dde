"""A hanging net of masses and ropes built on a planform grid or any net.

The edges of the grid (a structured :class:`~shellform.geometry.grids.QuadGrid`
or an unstructured :class:`~shellform.geometry.meshnet.MeshNet` of quads,
triangles or lines) become ropes, the nodes become masses, and the chosen
nodes become suspension points (fixed supports). Rope rest lengths are
``(1 + sc)`` times the edge lengths of the planform grid (the slack
coefficient ``sc`` of the MRA paper), so suspension points may be lifted
(edge frames, arches) without changing the ropes. A grid edge between two
suspension points held in every direction (along an edge frame, around the
rim of a net hung from its boundary) is part of the support, not of the net:
it is left out of the model and its weight hangs on the two supports.
Edge cables are boundary edges given a rope group of their own, with their
own axial stiffness, slack and mass.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import NamedTuple

import numpy as np

from ..assembly import System, build_system
from ..errors import ModelError
from ..geometry.grids import QuadGrid
from ..geometry.meshnet import MeshNet
from ..geometry.selection import nearest_nodes, nodes_in_box, nodes_on_polyline
from ..model import SLIDE_STIFFNESS_RATIO, STANDARD_GRAVITY, Structure, parse_dofs

#: keys of a support entry that choose nodes
SELECT_KEYS = ("groups", "positions", "nodes", "frames", "near", "box", "curve", "z")
#: a family number for each edge cable group (grid ropes are 0 and 1)
CABLE_FAMILY = 2


@dataclass
class HangingNet:
    """A rope net ready for form finding.

    Attributes
    ----------
    grid : QuadGrid or MeshNet
        The planform grid or net (reference geometry of the ropes).
    structure : Structure
        Nodes (planform, with lifted suspension points), rope groups
        ``"ropes_i"`` and ``"ropes_j"`` (the two families of grid lines; one
        group ``"ropes"`` on an unstructured net), ``"cable_0"``, ... (edge
        cables), supports, point masses and gravity.
    supports : ndarray
        Node numbers of the suspension points.
    rope_edges : ndarray, shape (m, 2)
        The ropes of the model, in the order of the two groups (``i`` family
        first). Grid edges between two suspension points held in every
        direction are not among them (``info["held_ropes"]``): they cannot
        move, so :func:`hanging_net` hangs their weight on the supports instead.
    family : ndarray, shape (m,)
        0 for ropes along ``i`` (every rope of an unstructured net), 1 along
        ``j``, :data:`CABLE_FAMILY` for edge cables.
    """

    grid: QuadGrid | MeshNet
    structure: Structure
    supports: np.ndarray
    rope_edges: np.ndarray
    family: np.ndarray
    info: dict = field(default_factory=dict)

    def system(self) -> System:
        return build_system(self.structure)

    @property
    def rope_groups(self):
        return [g for g in self.structure.groups if g.kind == "rope"]

    @property
    def rest_length(self) -> np.ndarray:
        return np.concatenate([g.rest_length for g in self.rope_groups])

    @property
    def EA(self) -> np.ndarray:
        return np.concatenate([g.EA for g in self.rope_groups])

    def total_weight(self) -> float:
        """Weight of all nodal masses plus the nodal loads' magnitude [N]."""
        s = self.structure
        g = np.linalg.norm(s.gravity) if s.gravity is not None else 0.0
        loads = sum(float(np.linalg.norm(c.forces, axis=1).sum()) for c in s.load_cases)
        return float(s.nodal_mass().sum() * g + loads)


#: keys of a support entry that let its nodes slide on a tilted plane or line (Structure.slide) or along a curve
#: (Structure.slide_along)
SLIDE_KEYS = ("slide", "slide_direction", "slide_curve", "slide_stiffness_ratio")


def add_sliding_support(structure: Structure, nodes, entry: dict) -> None:
    """Let ``nodes`` slide as a support entry says: on a plane or line through each node, or along a curve
    (``slide_curve``, or else the ``curve`` that chose the nodes)."""
    ratio = entry.get("slide_stiffness_ratio") or SLIDE_STIFFNESS_RATIO
    if entry["slide"] == "curve":
        curve = entry.get("slide_curve")
        structure.slide_along(nodes, entry.get("curve") if curve is None else curve, ratio, entry.get("tolerance"))
    else:
        structure.slide(nodes, entry["slide"], entry["slide_direction"], ratio)


def support_nodes(grid: QuadGrid | MeshNet, spec: dict | None) -> tuple[np.ndarray, np.ndarray]:
    """Suspension points from a specification; returns ``(nodes, lifted_z)``.

    ``spec`` keys (all optional, combined):

    * ``groups``: names of node sets of the grid (``"boundary"``, ``"corners"``,
      ``"south"``, ``"sw"``, ...; of a gmsh planform or a mesh file its own sets);
    * ``positions``: structured positions ``[[i, j], ...]`` (negative counts from the end);
    * ``nodes``: node numbers;
    * ``near``: points ``[[x, y, z], ...]``, the node nearest to each;
    * ``box``: two corners ``[[x0, y0, z0], [x1, y1, z1]]``, the nodes inside;
    * ``curve``: a polyline ``[[x, y, z], ...]``, the nodes within ``tolerance`` of it;
    * ``z``: the nodes at this height (within ``z_tolerance``, default 1e-6 m);
    * ``frames``: edge frames, each ``{"from": [i, j], "to": [i, j], "rise": h}``: all nodes on
      the straight grid line between the two positions, lifted on a parabolic arch of rise ``h``
      (default 0).

    ``positions`` and ``frames`` need a structured grid. ``lifted_z`` holds
    the height added to each node (zero except on frames with a rise).
    """
    spec = spec or {}
    unknown = set(spec) - set(SELECT_KEYS) - {"dofs", "tolerance", "z_tolerance"} - set(SLIDE_KEYS)
    if unknown:
        raise ModelError(f"supports: unknown keys {sorted(unknown)}; expected {', '.join(SELECT_KEYS)}, tolerance, "
                         f"dofs, {', '.join(SLIDE_KEYS)}")
    chosen = select_nodes(grid, spec, "supports")
    lift = np.zeros(grid.n_nodes)
    for k, frame in enumerate(spec.get("frames") or []):
        nodes, s = frame_nodes(grid, frame, k)
        rise = float(frame.get("rise", 0.0))
        lift[nodes] = np.maximum(lift[nodes], 4.0 * rise * s * (1.0 - s))
        chosen = np.union1d(chosen, nodes)
    if not chosen.size:
        raise ModelError("supports: no suspension points given (use groups, positions, nodes, near, box, curve "
                         "or frames)")
    return chosen, lift


def select_nodes(grid: QuadGrid | MeshNet, spec: dict, what: str) -> np.ndarray:
    """The nodes a specification chooses by ``groups``, ``positions``, ``nodes``, ``near``, ``box`` and ``curve``."""
    chosen = [np.zeros(0, dtype=np.int64)]
    for name in spec.get("groups") or []:
        chosen.append(grid.group(name))
    structured = ("positions", "frames")
    if not grid.structured and any(spec.get(k) for k in structured):
        key = next(k for k in structured if spec.get(k))
        raise ModelError(f"{what}: {key} need a structured grid (grid positions [i, j]); this net is unstructured: "
                         "choose nodes by groups, nodes, near, box or curve")
    if spec.get("positions"):
        chosen.append(grid.nodes_at(spec["positions"]))
    if spec.get("nodes") is not None and len(spec["nodes"]):
        nodes = np.asarray(spec["nodes"], dtype=np.int64)
        if np.any((nodes < 0) | (nodes >= grid.n_nodes)):
            raise ModelError(f"{what}: node numbers must lie in 0..{grid.n_nodes - 1}, got {spec['nodes']}")
        chosen.append(nodes)
    if spec.get("near") is not None:
        chosen.append(nearest_nodes(grid.nodes, spec["near"]))
    if spec.get("box") is not None:
        at = nodes_in_box(grid.nodes, spec["box"])
        if not at.size:
            raise ModelError(f"{what}: no node lies inside the box {np.asarray(spec['box']).tolist()}")
        chosen.append(at)
    if spec.get("curve") is not None:
        tol = spec.get("tolerance")
        tol = 1e-6 * max(float(np.ptp(grid.nodes, axis=0).max()), 1.0) if tol is None else float(tol)
        at = nodes_on_polyline(grid.nodes, spec["curve"], tol)
        if not at.size:
            raise ModelError(f"{what}: no node lies within {tol:g} m of the curve")
        chosen.append(at)
    if spec.get("z") is not None:
        tol = float(spec.get("z_tolerance", 1e-6))
        at = np.flatnonzero(np.abs(grid.nodes[:, 2] - float(spec["z"])) <= tol)
        if not at.size:
            raise ModelError(f"{what}: no node lies at z = {spec['z']} (within {tol:g} m); the nodes span z = "
                             f"{grid.nodes[:, 2].min():.6g} .. {grid.nodes[:, 2].max():.6g}")
        chosen.append(at)
    return np.unique(np.concatenate(chosen))


def frame_nodes(grid: QuadGrid, frame: dict, k: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Nodes on a straight grid line between two structured positions, with their arc parameter in [0, 1]."""
    try:
        a, b = np.asarray(frame["from"], dtype=np.int64), np.asarray(frame["to"], dtype=np.int64)
    except KeyError:
        raise ModelError(f"supports: frame {k} needs 'from' and 'to' positions [i, j]") from None
    ni, nj = grid.shape
    a = np.where(a < 0, a + (ni, nj), a)
    b = np.where(b < 0, b + (ni, nj), b)
    if a[0] != b[0] and a[1] != b[1]:
        raise ModelError(f"supports: frame {k} from {a.tolist()} to {b.tolist()} is not along one grid line")
    n = int(np.abs(b - a).max()) + 1
    pos = np.round(a[None, :] + np.linspace(0, 1, n)[:, None] * (b - a)[None, :]).astype(np.int64)
    nodes = grid.nodes_at(pos)
    s = np.linspace(0.0, 1.0, n)
    return nodes, s


@dataclass(frozen=True)
class NetOptions:
    """The ropes, masses and loads of a hanging net (:func:`hanging_net`).

    Attributes
    ----------
    slack : float, (float, float) or array_like
        Slack coefficient(s): one for all ropes, one per family (``i``, ``j``),
        or one per grid edge (in the order of ``grid.edges``).
    EA : float or array_like, optional
        Axial stiffness of the ropes [N], one for all or one per grid edge
        (in the order of ``grid.edges``). Default ``stiffness_ratio`` times
        the net's weight, so rope strains stay around ``1 / stiffness_ratio``
        or less: nearly inextensible ropes.
    mass_per_length : float
        Rope mass [kg/m] (lumped half to each end node).
    node_mass : float or array_like
        Extra point mass at every node [kg].
    gravity : (3,) array_like
    loads : (n, 3) array_like, optional
        Extra nodal forces [N].
    stiffness_ratio : float
        See ``EA``.
    cables : sequence of dict
        Edge cables: each chooses nodes as a support does (``groups``,
        ``nodes``, ``near``, ``box``, ``curve``, ``tolerance``) and takes the
        boundary edges with both ends among them (every chosen edge of a net
        of lines) into a rope group of its own, with ``EA`` [N] (required),
        ``slack`` (default 0) and ``mass_per_length`` [kg/m] (default the
        ropes').
    """

    slack: float | tuple | np.ndarray = 0.0
    EA: float | np.ndarray | None = None
    mass_per_length: float = 1.0
    node_mass: float | np.ndarray = 0.0
    gravity: tuple | np.ndarray = STANDARD_GRAVITY
    loads: np.ndarray | None = None
    stiffness_ratio: float = 1.0e4
    cables: tuple = ()


def hanging_net(grid: QuadGrid | MeshNet, supports: dict | list | None = None, options: NetOptions | None = None,
                **fields) -> HangingNet:
    """Build the MRA model of a net hanging from its suspension points.

    Parameters
    ----------
    grid : QuadGrid or MeshNet
        Planform grid or net; its edges become ropes.
    supports : dict or list of dict
        One entry or several, each as in :func:`support_nodes`, with its own
        ``dofs`` (default ``"xyz"``): the translations of its nodes that are
        held. A node held along some axes slides in the others (``"z"``: on a
        horizontal plane; ``"yz"``: along a line parallel to x).
    options : NetOptions, optional
        The ropes, masses, loads and edge cables (defaults: :class:`NetOptions`).
    **fields
        Fields of :class:`NetOptions` given one by one
        (``hanging_net(grid, supports, slack=0.05)``): they override those of ``options``.
    """
    o = replace(options or NetOptions(), **fields)
    chosen, held_axes = _chosen_supports(grid, supports)
    lift = np.max([c[1] for c in chosen], axis=0)
    edges = grid.edges
    family = grid.edge_direction()
    order = np.argsort(family, kind="stable")
    edges, family = edges[order], family[order]
    flat_length = np.linalg.norm(grid.nodes[edges[:, 1]] - grid.nodes[edges[:, 0]], axis=1)
    sc = _slack_coefficients(o.slack, family, order)
    cable = _cable_of_edges(grid, edges, o.cables)

    positions = grid.nodes.copy()
    positions[:, 2] += lift
    s = Structure(positions)
    point_mass = _node_masses(o, grid.n_nodes)
    rest = (1.0 + sc) * flat_length
    mass_per_length = np.full(len(edges), float(o.mass_per_length))
    for k, c in enumerate(o.cables):
        on = cable == k
        sc[on] = _cable_value(c, "slack", 0.0, k)
        rest[on] = (1.0 + sc[on]) * flat_length[on]
        mass_per_length[on] = _cable_value(c, "mass_per_length", o.mass_per_length, k)
    held = np.all(held_axes.all(axis=1)[edges], axis=1)
    if held.all():
        raise ModelError("ropes: every rope joins two suspension points; there is no net left to hang")
    # A rope whose two ends are held in every direction cannot move: its tension is set by
    # where the supports are (an arched frame stretches the ropes along it by its rise), not
    # by the net. It is left out of the model, its weight hanging on its two ends, so that
    # the reactions and rope reports are the net's own.
    point_mass = point_mass + _end_masses(edges[held], 0.5 * mass_per_length[held] * rest[held], grid.n_nodes)
    if np.any(point_mass > 0):
        s.add_point_mass(np.arange(grid.n_nodes), point_mass)
    s.set_gravity(o.gravity)
    if o.loads is not None:
        s.add_load(np.arange(grid.n_nodes), np.asarray(o.loads, dtype=float), scaled=False)
    cable_mass = float((mass_per_length * rest)[~held & (cable >= 0)].sum())
    EA = _rope_stiffness(o, point_mass, rest[~held & (cable < 0)], order, cable_mass)
    ropes = _RopeEdges(edges, family, cable, held, rest, mass_per_length)
    kept = _add_rope_groups(s, o, ropes, EA, grid.structured)
    out_family = np.where(cable[kept] >= 0, CABLE_FAMILY, family[kept])
    entries = [supports] if supports is None or isinstance(supports, dict) else list(supports)
    for (nodes, _, dofs), e in zip(chosen, entries):
        if (e or {}).get("slide"):
            add_sliding_support(s, nodes, e)
        else:
            s.fix(nodes, dofs)
    all_dofs = {dofs for _, _, dofs in chosen}
    nodes_sup = np.unique(np.concatenate([c[0] for c in chosen]))
    return HangingNet(grid=grid, structure=s, supports=nodes_sup, rope_edges=edges[kept], family=out_family,
                      info={"slack": sc[kept], "flat_length": flat_length[kept],
                            "held_ropes": edges[held], "support_dofs": all_dofs.pop() if len(all_dofs) == 1 else None,
                            "n_cable_ropes": int(np.count_nonzero(cable[kept] >= 0))})


def _chosen_supports(grid, supports) -> tuple[list, np.ndarray]:
    """Each support entry's nodes, lift and held components; and which components of every node are held."""
    entries = [supports] if supports is None or isinstance(supports, dict) else list(supports)
    # a node that slides on a tilted plane or line holds no coordinate axis: none of its own is fixed
    chosen = [(*support_nodes(grid, e), "" if (e or {}).get("slide") else (e or {}).get("dofs", "xyz"))
              for e in entries]
    held_axes = np.zeros((grid.n_nodes, 3), dtype=bool)
    for nodes, _, dofs in chosen:
        if dofs:
            held_axes[np.ix_(nodes, parse_dofs(dofs, "support dofs"))] = True
    return chosen, held_axes


class _RopeEdges(NamedTuple):
    """The grid's edges as ropes: ends, family, edge cable (-1: none), held at both ends, rest length, mass."""

    edges: np.ndarray
    family: np.ndarray
    cable: np.ndarray
    held: np.ndarray
    rest: np.ndarray
    mass_per_length: np.ndarray


def _add_rope_groups(s: Structure, o: NetOptions, r: _RopeEdges, EA: np.ndarray, structured: bool) -> np.ndarray:
    """The net's ropes (one group per family of a structured grid) and each edge cable as groups of ``s``.

    ``EA`` holds the stiffness of the net's own ropes, in edge order. Returns
    the edges kept (all but the held ones), in the order of the groups.
    """
    net_rope = ~r.held & (r.cable < 0)
    names = ((0, "ropes_i"), (1, "ropes_j")) if structured else ((0, "ropes"),)
    kept = []
    for fam, name in names:
        sel = np.flatnonzero((r.family == fam) & net_rope)
        if sel.size:
            s.add_ropes(r.edges[sel], EA=EA[sel], rest_length=r.rest[sel], mass_per_length=o.mass_per_length,
                        name=name)
            kept.append(sel)
    for k, c in enumerate(o.cables):
        sel = np.flatnonzero((r.cable == k) & ~r.held)
        if sel.size:
            s.add_ropes(r.edges[sel], EA=_cable_value(c, "EA", None, k), rest_length=r.rest[sel],
                        mass_per_length=r.mass_per_length[sel], name=c.get("name") or f"cable_{k}")
            kept.append(sel)
    return np.concatenate(kept)


def _cable_value(cable: dict, key: str, default, k: int):
    """A number of edge cable ``k`` (its default when absent; required when the default is None)."""
    v = cable.get(key)
    if v is None:
        if default is None:
            raise ModelError(f"cables[{k}]: {key} is required")
        return float(default)
    v = float(v)
    bad = {"EA": v <= 0, "slack": v <= -1.0, "mass_per_length": v < 0}[key]
    if bad or not np.isfinite(v):
        raise ModelError(f"cables[{k}]: {key} = {v!r} is out of range")
    return v


def _cable_of_edges(grid, edges: np.ndarray, cables) -> np.ndarray:
    """The edge cable of every edge (-1: none); a later cable does not take an earlier one's edges."""
    out = np.full(len(edges), -1, dtype=np.int64)
    if not cables:
        return out
    n = grid.n_nodes
    border = grid.boundary_edges() if (grid.structured or grid.faces) else grid.edges
    code = edges[:, 0] * n + edges[:, 1]
    on_border = np.isin(code, border[:, 0] * n + border[:, 1])
    for k, c in enumerate(cables):
        spec = {key: c[key] for key in ("groups", "nodes", "near", "box", "curve", "tolerance", "positions")
                if c.get(key) is not None}
        nodes = select_nodes(grid, spec, f"cables[{k}]")
        take = on_border & np.isin(edges, nodes).all(axis=1) & (out < 0)
        if not take.any():
            raise ModelError(f"cables[{k}]: its nodes join no boundary edge of the net (a cable runs along the "
                             "boundary, between neighbouring boundary nodes it names)")
        out[take] = k
    return out


def _slack_coefficients(slack, family: np.ndarray, order: np.ndarray) -> np.ndarray:
    """One slack coefficient per rope (ropes sorted by family, ``order`` from the grid's edges)."""
    sc = np.asarray(slack, dtype=float)
    if sc.ndim == 0:
        sc = np.full(len(family), float(sc))
    elif sc.shape == (2,):
        sc = sc[family]
    elif sc.shape == (len(order),):
        sc = sc[order]
    else:
        raise ModelError(f"ropes: slack must be a number, two numbers (per family) or one per rope, got shape {sc.shape}")
    if not np.all(np.isfinite(sc)) or np.any(sc <= -1.0):
        raise ModelError("ropes: slack coefficients must be finite and greater than -1")
    return sc


def _node_masses(o: NetOptions, n_nodes: int) -> np.ndarray:
    """The extra point mass of every node, checked along with the ropes' mass per length."""
    point_mass = np.broadcast_to(np.asarray(o.node_mass, dtype=float), (n_nodes,))
    if np.any(point_mass < 0) or not np.all(np.isfinite(point_mass)):
        raise ModelError("masses: node_mass must be finite and non-negative")
    if o.mass_per_length < 0:
        raise ModelError(f"ropes: mass_per_length must be non-negative, got {o.mass_per_length}")
    return point_mass


def _rope_stiffness(o: NetOptions, point_mass: np.ndarray, net_rest: np.ndarray, order: np.ndarray,
                    cable_mass: float = 0.0) -> np.ndarray:
    """EA of every rope (sorted by family): as given, or ``stiffness_ratio`` times the net's weight.

    ``point_mass`` holds the held ropes' mass by now; ``net_rest`` are the
    rest lengths of the ropes left in the model, ``cable_mass`` the mass of
    the edge cables in it.
    """
    EA = o.EA
    if EA is None:
        weight = float((point_mass.sum() + o.mass_per_length * net_rest.sum() + cable_mass)
                       * np.linalg.norm(o.gravity))
        if o.loads is not None:
            weight += float(np.linalg.norm(np.asarray(o.loads, dtype=float), axis=-1).sum())
        if weight <= 0:
            raise ModelError("ropes: the net has no weight and no load; give EA explicitly")
        EA = o.stiffness_ratio * weight
    EA = np.asarray(EA, dtype=float)
    if EA.shape == (len(order),):
        EA = EA[order]
    elif EA.ndim != 0:
        raise ModelError(f"ropes: EA must be a number or one per grid edge ({len(order)}), got shape {EA.shape}")
    return np.broadcast_to(EA, (len(order),))


def _end_masses(edges: np.ndarray, half_mass: np.ndarray, n_nodes: int) -> np.ndarray:
    """Nodal masses of ropes lumped half to each end."""
    return (np.bincount(edges[:, 0], half_mass, minlength=n_nodes)
            + np.bincount(edges[:, 1], half_mass, minlength=n_nodes))
