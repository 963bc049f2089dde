"""A hanging net of masses and ropes built on a structured quad grid.

The quad edges become ropes, the grid nodes become masses, and the chosen
nodes become suspension points (fixed supports). Rope rest lengths are
``(1 + sc)`` times the edge lengths of the planform grid (the slack
coefficient ``sc`` of the MRA paper), so suspension points may be lifted
(edge frames, arches) without changing the ropes. A grid edge between two
suspension points held in every direction (along an edge frame, around the
rim of a net hung from its boundary) is part of the support, not of the net:
it is left out of the model and its weight hangs on the two supports.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from ..assembly import System, build_system
from ..errors import ModelError
from ..geometry.grids import QuadGrid
from ..model import STANDARD_GRAVITY, Structure, parse_dofs


@dataclass
class HangingNet:
    """A rope net ready for form finding.

    Attributes
    ----------
    grid : QuadGrid
        The planform grid (reference geometry of the ropes).
    structure : Structure
        Nodes (planform, with lifted suspension points), rope groups
        ``"ropes_i"`` and ``"ropes_j"`` (the two families of grid lines),
        supports, point masses and gravity.
    supports : ndarray
        Node numbers of the suspension points.
    rope_edges : ndarray, shape (m, 2)
        The ropes of the model, in the order of the two groups (``i`` family
        first). Grid edges between two suspension points held in every
        direction are not among them (``info["held_ropes"]``): they cannot
        move, so :func:`hanging_net` hangs their weight on the supports instead.
    family : ndarray, shape (m,)
        0 for ropes along ``i``, 1 along ``j``.
    """

    grid: QuadGrid
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


def support_nodes(grid: QuadGrid, spec: dict | None) -> tuple[np.ndarray, np.ndarray]:
    """Suspension points from a specification; returns ``(nodes, lifted_z)``.

    ``spec`` keys (all optional, combined):

    * ``groups``: names of node sets of the grid (``"boundary"``, ``"corners"``,
      ``"south"``, ``"sw"``, ...);
    * ``positions``: structured positions ``[[i, j], ...]`` (negative counts from the end);
    * ``nodes``: node numbers;
    * ``frames``: edge frames, each ``{"from": [i, j], "to": [i, j], "rise": h}``: all nodes on
      the straight grid line between the two positions, lifted on a parabolic arch of rise ``h``
      (default 0).

    ``lifted_z`` holds the height added to each node (zero except on frames with a rise).
    """
    spec = spec or {}
    unknown = set(spec) - {"groups", "positions", "nodes", "frames", "dofs"}
    if unknown:
        raise ModelError(f"supports: unknown keys {sorted(unknown)}; expected groups, positions, nodes, frames, dofs")
    chosen = []
    lift = np.zeros(grid.n_nodes)
    for name in spec.get("groups", []):
        chosen.append(grid.group(name))
    if spec.get("positions"):
        chosen.append(grid.nodes_at(spec["positions"]))
    if spec.get("nodes"):
        nodes = np.asarray(spec["nodes"], dtype=np.int64)
        if np.any((nodes < 0) | (nodes >= grid.n_nodes)):
            raise ModelError(f"supports: node numbers must lie in 0..{grid.n_nodes - 1}, got {spec['nodes']}")
        chosen.append(nodes)
    for k, frame in enumerate(spec.get("frames", [])):
        nodes, s = frame_nodes(grid, frame, k)
        rise = float(frame.get("rise", 0.0))
        lift[nodes] = np.maximum(lift[nodes], 4.0 * rise * s * (1.0 - s))
        chosen.append(nodes)
    if not chosen:
        raise ModelError("supports: no suspension points given (use groups, positions, nodes or frames)")
    return np.unique(np.concatenate(chosen)), lift


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
    """

    slack: float | tuple | np.ndarray = 0.0
    EA: float | np.ndarray | None = None
    mass_per_length: float = 1.0
    node_mass: float | np.ndarray = 0.0
    gravity: tuple | np.ndarray = STANDARD_GRAVITY
    loads: np.ndarray | None = None
    stiffness_ratio: float = 1.0e4


def hanging_net(grid: QuadGrid, supports: dict | None = None, options: NetOptions | None = None,
                **fields) -> HangingNet:
    """Build the MRA model of a net hanging from its suspension points.

    Parameters
    ----------
    grid : QuadGrid
        Planform grid; its edges become ropes.
    supports : dict
        See :func:`support_nodes`; ``dofs`` (default ``"xyz"``) says which
        translations of the suspension points are held.
    options : NetOptions, optional
        The ropes, masses and loads (defaults: :class:`NetOptions`).
    **fields
        Fields of :class:`NetOptions` given one by one
        (``hanging_net(grid, supports, slack=0.05)``): they override those of ``options``.
    """
    o = replace(options or NetOptions(), **fields)
    nodes_sup, lift = support_nodes(grid, supports)
    dofs = (supports or {}).get("dofs", "xyz")
    edges = grid.edges
    family = grid.edge_direction()
    order = np.argsort(family, kind="stable")
    edges, family = edges[order], family[order]
    flat_length = np.linalg.norm(grid.nodes[edges[:, 1]] - grid.nodes[edges[:, 0]], axis=1)
    sc = _slack_coefficients(o.slack, family, order)

    positions = grid.nodes.copy()
    positions[:, 2] += lift
    s = Structure(positions)
    point_mass = _node_masses(o, grid.n_nodes)
    rest = (1.0 + sc) * flat_length
    held = _held_ropes(edges, nodes_sup, dofs)
    if held.all():
        raise ModelError("ropes: every rope joins two suspension points; there is no net left to hang")
    # A rope whose two ends are held in every direction cannot move: its tension is set by
    # where the supports are (an arched frame stretches the ropes along it by its rise), not
    # by the net. It is left out of the model, its weight hanging on its two ends, so that
    # the reactions and rope reports are the net's own.
    point_mass = point_mass + _end_masses(edges[held], 0.5 * o.mass_per_length * rest[held], grid.n_nodes)
    if np.any(point_mass > 0):
        s.add_point_mass(np.arange(grid.n_nodes), point_mass)
    s.set_gravity(o.gravity)
    if o.loads is not None:
        s.add_load(np.arange(grid.n_nodes), np.asarray(o.loads, dtype=float), scaled=False)
    EA = _rope_stiffness(o, point_mass, rest[~held], order)
    net_rope = ~held
    for fam, name in ((0, "ropes_i"), (1, "ropes_j")):
        sel = (family == fam) & net_rope
        if np.any(sel):
            s.add_ropes(edges[sel], EA=EA[sel], rest_length=rest[sel], mass_per_length=o.mass_per_length, name=name)
    s.fix(nodes_sup, dofs)
    return HangingNet(grid=grid, structure=s, supports=nodes_sup, rope_edges=edges[net_rope],
                      family=family[net_rope],
                      info={"slack": sc[net_rope], "flat_length": flat_length[net_rope], "held_ropes": edges[held],
                            "support_dofs": dofs})


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


def _rope_stiffness(o: NetOptions, point_mass: np.ndarray, net_rest: np.ndarray, order: np.ndarray) -> np.ndarray:
    """EA of every rope (sorted by family): as given, or ``stiffness_ratio`` times the net's weight.

    ``point_mass`` holds the held ropes' mass by now; ``net_rest`` are the
    rest lengths of the ropes left in the model.
    """
    EA = o.EA
    if EA is None:
        weight = float((point_mass.sum() + o.mass_per_length * net_rest.sum()) * np.linalg.norm(o.gravity))
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


def _held_ropes(edges: np.ndarray, supports: np.ndarray, dofs: str) -> np.ndarray:
    """Ropes whose two ends are suspension points held in all three directions."""
    if len(parse_dofs(dofs, "support dofs")) < 3:
        return np.zeros(len(edges), dtype=bool)  # sliding supports: a rope between two of them can move
    return np.isin(edges, supports).all(axis=1)


def _end_masses(edges: np.ndarray, half_mass: np.ndarray, n_nodes: int) -> np.ndarray:
    """Nodal masses of ropes lumped half to each end."""
    return (np.bincount(edges[:, 0], half_mass, minlength=n_nodes)
            + np.bincount(edges[:, 1], half_mass, minlength=n_nodes))
