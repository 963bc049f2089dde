"""Networks of discrete elastic rods inside a :class:`~shellform.model.Structure`.

A rod is a polyline of existing structure nodes. :class:`RodNetwork` gives each
rod one twist DOF per edge (``Structure.add_twist_dofs``), registers its edges
as a member group of kind ``"rod"`` (so that supports checks, self-weight and
output see them), records rest lengths, Voronoi lengths and natural
curvature, and builds the stretching, bending and twisting effects for all
rods at once. Joints between rods are either

* *shared nodes*: both rods pass through the same node (exact coincidence), or
* *penalty joints*: two coincident nodes tied by the spring of Eq. (3) of the
  gridshell paper, ``E = 1/2 K_s |x_a - x_b|^2`` (:mod:`shellform.effects.joints`).

Boundary conditions are helpers on the network (clamped end, pinned end with
twist fixed or free, end rotation) plus :class:`NodePath` for nodes moved along
a prescribed path.

Example
-------
>>> nodes, rods, pairs = stack_polylines([line_a, line_b], merge=False)
>>> s = Structure(nodes)
>>> net = RodNetwork(s)
>>> for idx in rods:
...     net.add_rod(idx, **circular_section(E=1e11, G=1e11 / 3, radius=1e-3, density=1e3))
>>> net.add_joints(pairs, stiffness_ratio=1e4)
>>> net.pin(0, "start"); net.pin(0, "end"); ...
>>> system = build_rod_system(net)
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from ..errors import MechanismError, ModelError
from ..model import Structure, broadcast_property
from .kinematics import (
    ReferenceFrames,
    curvature_binormal,
    material_curvatures,
    material_frames,
    parallel_transport,
    perpendicular_director,
    signed_angle,
    space_parallel_directors,
)


@dataclass(frozen=True)
class Rod:
    """One rod of a network.

    Attributes
    ----------
    name : str
    index : int
        Position of the rod in the network.
    nodes : ndarray (N,)
        Structure node indices along the rod.
    edges : ndarray (N - 1,) or (N,) if closed
        Indices of its edges in the network's edge arrays.
    hinges : ndarray (N - 2,) or (N,) if closed
        Indices of its interior nodes in the network's hinge arrays.
    twist_dofs : ndarray
        Flat DOF index of the twist angle of each edge.
    closed : bool
    """

    name: str
    index: int
    nodes: np.ndarray
    edges: np.ndarray
    hinges: np.ndarray
    twist_dofs: np.ndarray
    closed: bool

    @property
    def n_edges(self) -> int:
        return len(self.edges)


def circular_section(E: float, G: float, radius: float, density: float = 0.0) -> dict[str, float]:
    """Stiffness and inertia per unit length of a solid circular rod.

    ``A = pi r^2``, ``I = pi r^4 / 4``, ``J = pi r^4 / 2`` (as in the gridshell
    paper). Returns keyword arguments for :meth:`RodNetwork.add_rod`.
    """
    for what, v in (("E", E), ("G", G), ("radius", radius)):
        if not np.isfinite(v) or v <= 0:
            raise ModelError(f"circular section: {what} must be positive and finite, got {v}")
    if not np.isfinite(density) or density < 0:
        raise ModelError(f"circular section: density must be non-negative, got {density}")
    A = np.pi * radius**2
    I = np.pi * radius**4 / 4
    J = np.pi * radius**4 / 2
    return {
        "EA": E * A,
        "EI": E * I,
        "GJ": G * J,
        "mass_per_length": density * A,
        "rotational_inertia": density * J,
    }


def stack_polylines(polylines: Sequence[np.ndarray], merge: bool = False, tol: float = 1e-9):
    """Put the points of several polylines into one node array.

    Parameters
    ----------
    polylines : sequence of (N_k, 3) arrays
    merge : bool
        Give coincident points of different polylines a single shared node
        (exact joints). Otherwise every polyline keeps its own nodes and the
        coincident pairs are returned for penalty joints.
    tol : float
        Distance below which points coincide, relative to the size of the
        point cloud.

    Returns
    -------
    nodes : ndarray (n, 3)
    indices : list of ndarray
        Node indices of each polyline.
    pairs : ndarray (k, 2)
        Coincident nodes of different polylines (empty when ``merge``).
    """
    from scipy.spatial import cKDTree

    pts = [np.asarray(p, dtype=float) for p in polylines]
    for k, p in enumerate(pts):
        if p.ndim != 2 or p.shape[1] != 3 or len(p) < 2:
            raise ModelError(f"polyline {k}: expected an array of shape (N, 3) with N >= 2, got {p.shape}")
        if not np.all(np.isfinite(p)):
            raise ModelError(f"polyline {k}: coordinates must be finite")
    allp = np.concatenate(pts)
    owner = np.concatenate([np.full(len(p), k) for k, p in enumerate(pts)])
    scale = max(float(np.ptp(allp, axis=0).max()), 1e-300)
    pairs = np.array(sorted(cKDTree(allp).query_pairs(tol * scale)), dtype=np.int64).reshape(-1, 2)
    pairs = pairs[owner[pairs[:, 0]] != owner[pairs[:, 1]]]
    offsets = np.concatenate([[0], np.cumsum([len(p) for p in pts])])
    if not merge:
        return allp, [np.arange(offsets[k], offsets[k + 1]) for k in range(len(pts))], pairs
    n = len(allp)
    adj = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    _, label = connected_components(adj, directed=False)
    # renumber in order of first appearance
    _, first = np.unique(label, return_index=True)
    order = np.argsort(first)
    new = np.empty(len(order), dtype=np.int64)
    new[order] = np.arange(len(order))
    index = new[label]
    nodes = allp[np.sort(first)]
    return nodes, [index[offsets[k] : offsets[k + 1]] for k in range(len(pts))], np.zeros((0, 2), dtype=np.int64)


def resample_polyline(points: np.ndarray, n_edges: int) -> np.ndarray:
    """``n_edges + 1`` points equally spaced in arc length along a polyline."""
    p = np.asarray(points, dtype=float)
    seg = np.linalg.norm(np.diff(p, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    if s[-1] <= 0:
        raise ModelError("resample_polyline: the polyline has zero length")
    target = np.linspace(0.0, s[-1], int(n_edges) + 1)
    return np.stack([np.interp(target, s, p[:, k]) for k in range(3)], axis=1)


class NodePath:
    """Nodes moved along a prescribed path: positions as a function of a parameter.

    Parameters
    ----------
    dofs : ndarray (k,)
        Flat DOF indices that follow the path.
    values : callable
        ``values(t) -> ndarray (k,)``: the DOF values at path parameter ``t``
        (time for dynamics, a step parameter for statics).

    Notes
    -----
    The DOFs must be constrained in the structure (``fix_dofs``); solvers then
    overwrite their values with ``values(t)`` instead of the reference value.
    """

    def __init__(self, dofs, values: Callable[[float], np.ndarray]):
        self.dofs = np.asarray(dofs, dtype=np.int64).ravel()
        self._values = values

    def __call__(self, t: float) -> np.ndarray:
        v = np.asarray(self._values(t), dtype=float).ravel()
        if v.shape != self.dofs.shape:
            raise ModelError(f"node path: expected {self.dofs.size} values at t={t}, got {v.size}")
        return v

    @classmethod
    def waypoints(cls, structure: Structure, nodes, times, positions) -> NodePath:
        """Piecewise-linear motion of ``nodes`` through ``positions`` (T, len(nodes), 3) at ``times`` (T,).

        Before the first time the nodes sit at the first waypoint, after the
        last at the last one. The nodes' translations are fixed in the
        structure.
        """
        nodes = np.atleast_1d(np.asarray(nodes, dtype=np.int64))
        times = np.asarray(times, dtype=float)
        pos = np.asarray(positions, dtype=float).reshape(len(times), len(nodes) * 3)
        if np.any(np.diff(times) <= 0):
            raise ModelError("node path: waypoint times must increase strictly")
        dofs = structure.node_dofs(nodes).ravel()
        structure.fix_dofs(dofs)

        def values(t):
            return np.array([np.interp(t, times, pos[:, k]) for k in range(pos.shape[1])])

        return cls(dofs, values)

    @classmethod
    def curve(cls, structure: Structure, nodes, positions: Callable[[float], np.ndarray]) -> NodePath:
        """Nodes following ``positions(t) -> (len(nodes), 3)``; their translations are fixed in the structure."""
        nodes = np.atleast_1d(np.asarray(nodes, dtype=np.int64))
        dofs = structure.node_dofs(nodes).ravel()
        structure.fix_dofs(dofs)
        return cls(dofs, lambda t: np.asarray(positions(t), dtype=float).ravel())


class RodNetwork:
    """Discrete elastic rods and joints on the nodes of a structure.

    Parameters
    ----------
    structure : Structure
        Holds the nodes; rods add twist DOFs and member groups to it.

    Attributes
    ----------
    rods : list of Rod
    edges : ndarray (m, 2)
        Node indices of all rod edges (oriented along their rods).
    edge_twist : ndarray (m,)
        Twist DOF of each edge.
    rest_length, EA, rotational_inertia : ndarray (m,)
        Per edge.
    hinge_edges : ndarray (h, 2)
        The edges (before, after) at each interior node.
    hinge_nodes : ndarray (h, 3)
    voronoi, EI, GJ, natural_twist : ndarray (h,)
        Per hinge; ``natural_twist`` is integrated (radians).
    natural_curvature : ndarray (h, 2, 2)
        Integrated natural material curvature of each hinge in the frame of
        its edge before ``[:, 0]`` and after ``[:, 1]``.
    joints : ndarray (k, 2)
        Penalty-joint node pairs; ``joint_stiffness`` (k,) their springs [N/m].
    """

    def __init__(self, structure: Structure):
        if not isinstance(structure, Structure):
            raise ModelError(f"rod network: expected a Structure, got {type(structure).__name__}")
        self.structure = structure
        self.rods: list[Rod] = []
        self._edge_parts: list[dict] = []
        self._hinge_parts: list[dict] = []
        self._joint_pairs: list[np.ndarray] = []
        self._joint_k: list[np.ndarray] = []
        self._frames: ReferenceFrames | None = None
        self._n_edges = 0
        self._n_hinges = 0

    # -- construction -----------------------------------------------------------------
    def add_rod(
        self,
        nodes,
        EA,
        EI,
        GJ,
        mass_per_length=0.0,
        rotational_inertia=0.0,
        natural_curvature="rest",
        natural_twist=0.0,
        rest_length=None,
        director=None,
        closed: bool = False,
        name: str | None = None,
    ) -> Rod:
        """Add a rod through existing structure nodes.

        Parameters
        ----------
        nodes : array_like of int (N,)
            Node indices along the rod, N >= 2 (N >= 3 when closed).
        EA : float or (n_edges,)
            Axial stiffness [N] per edge.
        EI, GJ : float or (n_hinges,)
            Bending and torsional stiffness [N m^2] per interior node.
        mass_per_length : float
            [kg/m], lumped to the nodes (self-weight and dynamics).
        rotational_inertia : float
            Mass moment of inertia about the axis per unit length [kg m]
            (``rho J``), lumped to the twist DOFs for dynamics.
        natural_curvature : {"rest", "straight"} or array (n_hinges, 2)
            ``"rest"``: the reference geometry is stress free.
            ``"straight"``: the rod is straight when unstressed.
            An array gives the natural material curvature [1/m] at each
            interior node (components along ``m1``, ``m2`` of the frames
            built from ``director``).
        natural_twist : float or (n_hinges,)
            Natural twist rate [rad/m] on top of the twist-free rest frames.
        rest_length : float or (n_edges,), optional
            Unstressed edge lengths; default: the reference edge lengths.
        director : array_like (3,), optional
            First material director of the first edge (projected perpendicular
            to it); default: vertical projected, or x for vertical edges.
            The frames of the other edges follow by space-parallel transport.
        closed : bool
            The last node connects back to the first (a ring).
        name : str, optional
        """
        if self._frames is not None:
            raise ModelError("rod network: rods cannot be added after the effects have been built")
        s = self.structure
        index = len(self.rods)
        name = name or f"rod{index}"
        idx = np.asarray(nodes)
        if idx.ndim != 1 or len(idx) < (3 if closed else 2):
            raise ModelError(f"rod {name!r}: expected a 1-D list of at least {3 if closed else 2} node indices")
        if not np.issubdtype(idx.dtype, np.integer):
            raise ModelError(f"rod {name!r}: node indices must be integers, got {idx.dtype}")
        idx = idx.astype(np.int64)
        if idx.min() < 0 or idx.max() >= s.n_nodes:
            bad = idx[(idx < 0) | (idx >= s.n_nodes)][0]
            raise ModelError(f"rod {name!r}: node index {bad} is out of range (the structure has {s.n_nodes} nodes)")
        if len(np.unique(idx)) != len(idx):
            raise ModelError(f"rod {name!r}: a node appears twice along the rod")
        e_nodes = np.stack([idx, np.roll(idx, -1)], axis=1) if closed else np.stack([idx[:-1], idx[1:]], axis=1)
        m = len(e_nodes)
        x = s.nodes
        vec = x[e_nodes[:, 1]] - x[e_nodes[:, 0]]
        length = np.linalg.norm(vec, axis=1)
        scale = max(float(np.ptp(x, axis=0).max()), 1e-300)
        short = np.flatnonzero(length <= 1e-12 * scale)
        if short.size:
            k = int(short[0])
            raise ModelError(f"rod {name!r}: edge {k} (nodes {e_nodes[k, 0]}-{e_nodes[k, 1]}) has zero length")
        rest = length if rest_length is None else broadcast_property(rest_length, m, f"rod {name!r} rest_length", item="edge")
        EA = broadcast_property(EA, m, f"rod {name!r} EA", item="edge")
        mpl = broadcast_property(mass_per_length, 1, f"rod {name!r} mass_per_length", True, "entry")[0]
        rot = broadcast_property(rotational_inertia, 1, f"rod {name!r} rotational_inertia", True, "entry")[0]

        # hinges: consecutive edge pairs (local numbering)
        local = np.arange(m)
        hinge_local = np.stack([local, np.roll(local, -1)], axis=1) if closed else np.stack([local[:-1], local[1:]], axis=1)
        h = len(hinge_local)
        EI = broadcast_property(EI, h, f"rod {name!r} EI", item="hinge") if h else np.zeros(0)
        GJ = broadcast_property(GJ, h, f"rod {name!r} GJ", item="hinge") if h else np.zeros(0)
        twist_rate = np.asarray(natural_twist, dtype=float)
        twist_rate = np.broadcast_to(twist_rate, (h,)) if twist_rate.ndim == 0 else twist_rate
        if twist_rate.shape != (h,) or not np.all(np.isfinite(twist_rate)):
            raise ModelError(f"rod {name!r}: natural_twist must be finite, a scalar or {h} values")

        # rest frames: space-parallel transport along the rod from the first director
        t = vec / length[:, None]
        first = np.zeros((m, 3))
        if director is None:
            first[0] = perpendicular_director(t[:1])[0]
        else:
            d = np.asarray(director, dtype=float)
            if d.shape != (3,) or not np.all(np.isfinite(d)):
                raise ModelError(f"rod {name!r}: director must be 3 finite numbers")
            d = d - (d @ t[0]) * t[0]
            if np.linalg.norm(d) < 1e-8 * max(np.linalg.norm(np.asarray(director, float)), 1e-300):
                raise ModelError(f"rod {name!r}: director is parallel to the first edge")
            first[0] = d / np.linalg.norm(d)
        chain = np.arange(-1, m - 1)
        u = space_parallel_directors(t, first, chain)

        e0, e1 = hinge_local[:, 0], hinge_local[:, 1]
        voronoi = 0.5 * (rest[e0] + rest[e1])
        moved = parallel_transport(u[e0], t[e0], t[e1]) if h else np.zeros((0, 3))
        m_rest = signed_angle(moved, u[e1], t[e1]) if h else np.zeros(0)
        kb = curvature_binormal(t[e0], t[e1]) if h else np.zeros((0, 3))
        zero = np.zeros(h)
        omega = np.zeros((h, 2, 2))
        if isinstance(natural_curvature, str):
            if natural_curvature == "rest":
                for j, e in enumerate((e0, e1)):
                    m1, m2 = material_frames(u[e], t[e], zero)
                    omega[:, j] = material_curvatures(kb, m1, m2)
            elif natural_curvature != "straight":
                raise ModelError(f"rod {name!r}: natural_curvature must be 'rest', 'straight' or an array")
        else:
            kappa = np.asarray(natural_curvature, dtype=float)
            if kappa.shape != (h, 2) or not np.all(np.isfinite(kappa)):
                raise ModelError(f"rod {name!r}: natural_curvature array must have shape ({h}, 2) and be finite")
            omega[:] = (kappa * voronoi[:, None])[:, None, :]

        twist = s.add_twist_dofs(m)
        s._add_group("rod", e_nodes, EA, rest, mpl, name)
        edges = self._n_edges + local
        hinges = self._n_hinges + np.arange(h)
        self._edge_parts.append(
            dict(nodes=e_nodes, twist=twist, rest=rest, EA=EA, rot=np.full(m, rot), director=u)
        )
        self._hinge_parts.append(
            dict(
                edges=self._n_edges + hinge_local,
                nodes=np.stack([e_nodes[e0, 0], e_nodes[e0, 1], e_nodes[e1, 1]], axis=1) if h else np.zeros((0, 3), int),
                voronoi=voronoi,
                EI=EI,
                GJ=GJ,
                omega=omega,
                tau=m_rest + twist_rate * voronoi,
            )
        )
        self._n_edges += m
        self._n_hinges += h
        rod = Rod(name=name, index=index, nodes=idx, edges=edges, hinges=hinges, twist_dofs=twist, closed=closed)
        self.rods.append(rod)
        return rod

    def add_joints(self, pairs, stiffness_ratio: float = 1.0e4, stiffness=None) -> None:
        """Tie coincident node pairs with penalty springs ``1/2 K_s |x_a - x_b|^2`` (Eq. 3).

        Parameters
        ----------
        pairs : array_like (k, 2)
            Node pairs to hold together.
        stiffness_ratio : float
            ``K_s`` as a multiple of the rods' own stiffness at the joint
            (:meth:`joint_reference_stiffness`): the penalty is then measured
            against the springs it competes with, independent of units and
            discretisation.
        stiffness : float or (k,), optional
            Absolute ``K_s`` [N/m], overriding ``stiffness_ratio``.
        """
        s = self.structure
        p = np.asarray(pairs)
        if p.size == 0:
            return
        if p.ndim != 2 or p.shape[1] != 2 or not np.issubdtype(p.dtype, np.integer):
            raise ModelError(f"joints: pairs must be integers of shape (k, 2), got {p.dtype} {p.shape}")
        p = p.astype(np.int64)
        if p.min() < 0 or p.max() >= s.n_nodes:
            raise ModelError(f"joints: node index out of range (the structure has {s.n_nodes} nodes)")
        same = np.flatnonzero(p[:, 0] == p[:, 1])
        if same.size:
            raise ModelError(f"joints: joint {int(same[0])} ties node {p[same[0], 0]} to itself")
        if stiffness is not None:
            k = broadcast_property(stiffness, len(p), "joints stiffness", item="joint")
        else:
            if not np.isfinite(stiffness_ratio) or stiffness_ratio <= 0:
                raise ModelError(f"joints: stiffness_ratio must be positive, got {stiffness_ratio}")
            k = stiffness_ratio * self.joint_reference_stiffness(p)
        self._joint_pairs.append(p)
        self._joint_k.append(k)

    def joint_reference_stiffness(self, pairs) -> np.ndarray:
        """The rods' stiffness at each joint [N/m]: the smaller of the two nodes' axial edge stiffness.

        A node's axial stiffness is the mean ``EA / L`` of the rod edges that
        touch it, the stiffest spring acting on that node; the joint compares
        its penalty with the softer of its two nodes.
        """
        p = np.asarray(pairs, dtype=np.int64)
        n = self.structure.n_nodes
        edges = self._edges_all()
        k = self._edge_all("EA") / self._edge_all("rest")
        total = np.bincount(edges.ravel(), np.repeat(k, 2), minlength=n)
        count = np.bincount(edges.ravel(), minlength=n)
        lonely = np.flatnonzero(count[p].min(axis=1) == 0)
        if lonely.size:
            j = int(lonely[0])
            raise ModelError(f"joints: joint {j} (nodes {p[j, 0]}-{p[j, 1]}) has a node that is on no rod")
        node_k = total / np.maximum(count, 1)
        return node_k[p].min(axis=1)

    # -- arrays over all rods ------------------------------------------------------------
    def _edges_all(self):
        return np.concatenate([d["nodes"] for d in self._edge_parts]) if self._edge_parts else np.zeros((0, 2), int)

    def _edge_all(self, key):
        return np.concatenate([d[key] for d in self._edge_parts]) if self._edge_parts else np.zeros(0)

    def _hinge_all(self, key, shape):
        parts = [d[key] for d in self._hinge_parts]
        return np.concatenate(parts) if parts else np.zeros((0,) + shape)

    @property
    def edges(self) -> np.ndarray:
        return self._edges_all()

    @property
    def edge_twist(self) -> np.ndarray:
        return self._edge_all("twist").astype(np.int64)

    @property
    def rest_length(self) -> np.ndarray:
        return self._edge_all("rest")

    @property
    def EA(self) -> np.ndarray:
        return self._edge_all("EA")

    @property
    def rotational_inertia(self) -> np.ndarray:
        """Twist inertia of each edge [kg m^2] (per-length value times rest length)."""
        return self._edge_all("rot") * self.rest_length

    @property
    def hinge_edges(self) -> np.ndarray:
        return self._hinge_all("edges", (2,)).astype(np.int64)

    @property
    def hinge_nodes(self) -> np.ndarray:
        return self._hinge_all("nodes", (3,)).astype(np.int64)

    @property
    def voronoi(self) -> np.ndarray:
        return self._hinge_all("voronoi", ())

    @property
    def EI(self) -> np.ndarray:
        return self._hinge_all("EI", ())

    @property
    def GJ(self) -> np.ndarray:
        return self._hinge_all("GJ", ())

    @property
    def natural_curvature(self) -> np.ndarray:
        return self._hinge_all("omega", (2, 2))

    @property
    def natural_twist(self) -> np.ndarray:
        return self._hinge_all("tau", ())

    @property
    def joints(self) -> np.ndarray:
        return np.concatenate(self._joint_pairs) if self._joint_pairs else np.zeros((0, 2), dtype=np.int64)

    @property
    def joint_stiffness(self) -> np.ndarray:
        return np.concatenate(self._joint_k) if self._joint_k else np.zeros(0)

    def hinge_stencils(self) -> np.ndarray:
        """DOFs of every bending/twisting stencil ``(x0, x1, x2, theta0, theta1)``, shape (h, 11)."""
        hn = self.hinge_nodes
        tw = self.edge_twist[self.hinge_edges]
        return np.concatenate([(3 * hn[:, :, None] + np.arange(3)).reshape(-1, 9), tw], axis=1)

    @property
    def frames(self) -> ReferenceFrames:
        """The reference frames shared by the bending and twisting effects (built on first use)."""
        if self._frames is None:
            s = self.structure
            self._frames = ReferenceFrames(
                s.n_nodes, self.edges, self.hinge_edges, s.reference_state(), self._edge_all_director()
            )
        return self._frames

    def _edge_all_director(self):
        return np.concatenate([d["director"] for d in self._edge_parts]) if self._edge_parts else np.zeros((0, 3))

    def rod(self, which) -> Rod:
        """A rod by index or name."""
        if isinstance(which, Rod):
            return which
        if isinstance(which, str):
            for r in self.rods:
                if r.name == which:
                    return r
            raise ModelError(f"rod network: no rod named {which!r}")
        try:
            return self.rods[int(which)]
        except (IndexError, ValueError, TypeError):
            raise ModelError(f"rod network: no rod {which!r} (the network has {len(self.rods)} rods)") from None

    # -- effects --------------------------------------------------------------------------
    def effects(self) -> list:
        """Stretching, bending, twisting (and joint) effects for all rods at once."""
        from ..effects.joints import PenaltyJoints
        from ..effects.rod_bend import RodBending
        from ..effects.rod_stretch import RodStretching
        from ..effects.rod_twist import RodTwisting

        if not self.rods:
            raise ModelError("rod network: no rods have been added")
        n_dof = self.structure.n_dof
        out = [RodStretching(n_dof, self.edges, self.EA, self.rest_length)]
        if self._n_hinges:
            stencil = self.hinge_stencils()
            out.append(RodBending(n_dof, self.frames, stencil, self.voronoi, self.EI, self.natural_curvature))
            out.append(RodTwisting(n_dof, self.frames, stencil, self.voronoi, self.GJ, self.natural_twist))
        if len(self.joints):
            out.append(PenaltyJoints(n_dof, self.joints, self.joint_stiffness))
        return out

    # -- boundary conditions ------------------------------------------------------------------
    def _end(self, rod, end):
        r = self.rod(rod)
        if r.closed:
            raise ModelError(f"rod {r.name!r}: a closed rod has no ends")
        if end in ("start", 0):
            return r, r.nodes[0], r.nodes[1], r.twist_dofs[0]
        if end in ("end", -1):
            return r, r.nodes[-1], r.nodes[-2], r.twist_dofs[-1]
        raise ModelError(f"rod {r.name!r}: end must be 'start' or 'end', got {end!r}")

    def clamp(self, rod, end="start") -> None:
        """Clamp a rod end: position, tangent (the end edge's two nodes) and twist of the end edge.

        In the continuum limit the clamp sits at the midpoint of the end edge,
        where the edge's frame lives: place the first two nodes astride the
        clamp point.
        """
        r, a, b, tw = self._end(rod, end)
        self.structure.fix([a, b])
        self.structure.fix_dofs([tw])

    def pin(self, rod, end="start", twist: str = "fixed") -> None:
        """Pin a rod end: position fixed, rotation free; the end edge's twist angle ``"fixed"`` or ``"free"``."""
        r, a, b, tw = self._end(rod, end)
        if twist not in ("fixed", "free"):
            raise ModelError(f"rod {r.name!r}: twist must be 'fixed' or 'free', got {twist!r}")
        self.structure.fix([a])
        if twist == "fixed":
            self.structure.fix_dofs([tw])

    def fix_twist(self, rod, end="start") -> None:
        """Hold the twist angle of a rod's end edge."""
        _, _, _, tw = self._end(rod, end)
        self.structure.fix_dofs([tw])

    def rotate_end(self, rod, end="end", angle: float = 1.0) -> None:
        """Prescribe the twist angle of an end edge: ``theta = mu * angle`` (mu: the prescribed parameter)."""
        _, _, _, tw = self._end(rod, end)
        self.structure.prescribe_dofs([tw], [float(angle)])

    # -- checks ------------------------------------------------------------------------------
    def check_supports(self) -> None:
        """Raise :class:`MechanismError` if a connected part can translate or a rod can spin freely.

        Connectivity counts member groups and penalty joints. A rod that is
        straight when unstressed and has no constrained twist angle can spin
        about itself at no cost; it is reported too.
        """
        s = self.structure
        n = s.n_nodes
        conn = [g.connectivity for g in s.groups] + [self.joints]
        conn = np.concatenate(conn) if conn else np.zeros((0, 2), dtype=np.int64)
        adj = coo_matrix((np.ones(len(conn)), (conn[:, 0], conn[:, 1])), shape=(n, n))
        n_comp, label = connected_components(adj, directed=False)
        cons = s.constrained_mask[: 3 * n].reshape(n, 3)
        for c in range(3):
            ok = np.bincount(label, cons[:, c].astype(float), minlength=n_comp) > 0
            bad = np.flatnonzero(~ok)
            if bad.size:
                members = np.flatnonzero(label == bad[0])
                listed = ", ".join(str(i) for i in members[:8]) + (", ..." if len(members) > 8 else "")
                raise MechanismError(
                    f"the structure is a mechanism: the connected part with nodes {listed} can translate "
                    f"freely along {'xyz'[c]}; add a support restraining {'xyz'[c]} on it"
                )
        omega = self.natural_curvature
        constrained = s.constrained_mask
        for r in self.rods:
            straight = not np.any(omega[r.hinges]) if len(r.hinges) else True
            if straight and not np.any(constrained[r.twist_dofs]):
                raise MechanismError(
                    f"rod {r.name!r} can spin about its own axis freely: fix the twist angle of at least "
                    "one of its edges (clamp, pin with twist fixed, or fix_twist)"
                )


def build_rod_system(network: RodNetwork, extra_effects=(), gravity_scaled: bool = False, check: bool = True):
    """A :class:`~shellform.assembly.System` for a structure with rods.

    Includes the rod effects (stretch, bend, twist, joints), the effects of
    the structure's other member groups (bars, ropes), its nodal loads, its
    self-weight when gravity is set, and ``extra_effects``.
    """
    from ..assembly import AxialBar, Rope, System
    from ..effects import gravity_effect, nodal_load_effects

    s = network.structure
    effects = network.effects()
    kinds = {"bar": AxialBar, "rope": Rope}
    for g in s.groups:
        if g.kind == "rod":
            continue
        if g.kind not in kinds:
            raise ModelError(f"member group {g.name!r}: unknown kind {g.kind!r}")
        e = kinds[g.kind](s.n_dof, g.connectivity, g.EA, g.rest_length)
        e.label = g.name
        effects.append(e)
    effects += nodal_load_effects(s)
    if s.gravity is not None:
        effects.append(gravity_effect(s, scales_with_load=gravity_scaled))
    effects += list(extra_effects)
    if check:
        network.check_supports()
    return System(s, effects, check=False)
