"""Networks of discrete elastic rods inside a :class:`~shellform.model.Structure`.

A rod is a polyline of existing structure nodes. :class:`RodNetwork` gives each
rod one twist DOF per edge (``Structure.add_twist_dofs``), registers its edges
as a member group of kind ``"rod"`` (so that supports checks, self-weight and
output see them), keeps the rod's arrays (rest lengths, Voronoi lengths,
natural curvature; :mod:`shellform.rods.rod_arrays`) and builds the
stretching, bending and twisting effects for all rods at once. Joints between
rods are either

* *shared nodes*: both rods pass through the same node (exact coincidence), or
* *penalty joints*: two coincident nodes tied by the spring of Eq. (3) of the
  gridshell paper, ``E = 1/2 K_s |x_a - x_b|^2`` (:mod:`shellform.effects.joints`).

Boundary conditions are helpers on the network (clamped end, pinned end with
twist fixed or free, end rotation) plus :class:`~shellform.rods.node_path.NodePath`
for nodes moved along a prescribed path.

Example
-------
>>> nodes, rods, pairs = stack_polylines([line_a, line_b], merge=False)
>>> s = Structure(nodes)
>>> net = RodNetwork(s)
>>> section = circular_section(E=1e11, G=1e11 / 3, radius=1e-3, density=1e3)
>>> for idx in rods:
...     net.add_rod(idx, section)
>>> net.add_joints(pairs, stiffness_ratio=1e4)
>>> net.pin(0, "start"); net.pin(0, "end"); ...
>>> system = build_rod_system(net)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from ..errors import MechanismError, ModelError
from ..model import Structure, broadcast_property
from ..effects.rod_kinematics import ReferenceFrames
from .rod_arrays import RodArrays, rod_arrays
from .section import RestShape, RodSection


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
    voronoi, EI, EI2, GJ, natural_twist : ndarray (h,)
        Per hinge; ``EI``, ``EI2`` the stiffness of the material curvatures
        ``omega_1``, ``omega_2``; ``natural_twist`` is integrated (radians).
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
        self._arrays: list[RodArrays] = []
        self._joint_pairs: list[np.ndarray] = []
        self._crossing_stiffness = 0.0
        self._anchor_held = False
        self._joint_k: list[np.ndarray] = []
        self._frames: ReferenceFrames | None = None
        self._n_edges = 0
        self._n_hinges = 0

    # -- construction -----------------------------------------------------------------
    def add_rod(
        self, nodes, section: RodSection, rest: RestShape = RestShape(), *, closed: bool = False,
        name: str | None = None,
    ) -> Rod:
        """Add a rod through existing structure nodes.

        Parameters
        ----------
        nodes : array_like of int (N,)
            Node indices along the rod, N >= 2 (N >= 3 when closed).
        section : RodSection
            Stiffness and inertia per unit length (:func:`circular_section` for a solid circular rod).
        rest : RestShape
            The stress-free shape; default: the reference geometry.
        closed : bool
            The last node connects back to the first (a ring).
        name : str, optional
        """
        if self._frames is not None:
            raise ModelError("rod network: rods cannot be added after the effects have been built")
        s = self.structure
        index = len(self.rods)
        name = name or f"rod{index}"
        arrays = rod_arrays(s.nodes, nodes, section, rest, closed, name)
        m, h = len(arrays.edge_nodes), len(arrays.hinge_edges)
        twist = s.add_twist_dofs(m)
        s._add_group("rod", arrays.edge_nodes, arrays.EA, arrays.rest_length, arrays.mass_per_length, name)
        rod = Rod(name=name, index=index, nodes=arrays.nodes, edges=self._n_edges + np.arange(m),
                  hinges=self._n_hinges + np.arange(h), twist_dofs=twist, closed=closed)
        self._n_edges += m
        self._n_hinges += h
        self._arrays.append(arrays)
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

    def anchor_held_twists(self) -> None:
        """Measure every held twist angle from a frame anchored where the twist was held
        (:meth:`~shellform.effects.rod_kinematics.ReferenceFrames.anchor`).

        With the frames carried along the path by time-parallel transport, a
        twist held at a support means something that depends on the steps
        taken to get there: equilibrium found in large steps and in small ones
        differs (by 2e-4 in the first critical load factor of a gridshell of
        timber laths pinned on its boundary). Anchored, it is a function of the
        edge's current direction alone. The edges are those whose twist DOF is
        constrained when the effects are built.
        """
        self._anchor_held = True

    def hold_crossing_angles(self, stiffness: float) -> None:
        """Rotational springs at every crossing of two rods, ``1/2 k (phi - phi_0)^2`` on the angle between them.

        A crossing is a node two rods share or a penalty joint; the angle is
        measured between the rods' chords through the crossing
        (:mod:`shellform.effects.joint_rotation`, :func:`~shellform.rods.crossings.crossing_chords`),
        ``phi_0`` in the structure's reference state. ``stiffness`` ``k``
        [N m/rad] >= 0; 0 leaves the joints free to turn (no springs).
        """
        k = float(stiffness)
        if not np.isfinite(k) or k < 0:
            raise ModelError(f"crossing angles: the rotational stiffness must be a number >= 0, got {stiffness!r}")
        self._crossing_stiffness = k

    def joint_reference_stiffness(self, pairs) -> np.ndarray:
        """The rods' stiffness at each joint [N/m]: the smaller of the two nodes' axial edge stiffness.

        A node's axial stiffness is the mean ``EA / L`` of the rod edges that
        touch it, the stiffest spring acting on that node; the joint compares
        its penalty with the softer of its two nodes.
        """
        p = np.asarray(pairs, dtype=np.int64)
        n = self.structure.n_nodes
        edges = self.edges
        k = self.EA / self.rest_length
        total = np.bincount(edges.ravel(), np.repeat(k, 2), minlength=n)
        count = np.bincount(edges.ravel(), minlength=n)
        lonely = np.flatnonzero(count[p].min(axis=1) == 0)
        if lonely.size:
            j = int(lonely[0])
            raise ModelError(f"joints: joint {j} (nodes {p[j, 0]}-{p[j, 1]}) has a node that is on no rod")
        node_k = total / np.maximum(count, 1)
        return node_k[p].min(axis=1)

    # -- arrays over all rods ------------------------------------------------------------
    def _joined(self, values, shape: tuple, dtype=float) -> np.ndarray:
        """One array of per-rod arrays, end to end (empty of ``shape`` without rods)."""
        parts = [values(rod, a) for rod, a in zip(self.rods, self._arrays)]
        return np.concatenate(parts) if parts else np.zeros((0,) + shape, dtype)

    @property
    def edges(self) -> np.ndarray:
        return self._joined(lambda rod, a: a.edge_nodes, (2,), int)

    @property
    def edge_twist(self) -> np.ndarray:
        return self._joined(lambda rod, a: rod.twist_dofs, ()).astype(np.int64)

    @property
    def rest_length(self) -> np.ndarray:
        return self._joined(lambda rod, a: a.rest_length, ())

    @property
    def EA(self) -> np.ndarray:
        return self._joined(lambda rod, a: a.EA, ())

    @property
    def rotational_inertia(self) -> np.ndarray:
        """Twist inertia of each edge [kg m^2] (per-length value times rest length)."""
        return self._joined(lambda rod, a: a.rotational_inertia * a.rest_length, ())

    @property
    def hinge_edges(self) -> np.ndarray:
        return self._joined(lambda rod, a: rod.edges[a.hinge_edges], (2,)).astype(np.int64)

    @property
    def hinge_nodes(self) -> np.ndarray:
        return self._joined(lambda rod, a: a.hinge_nodes, (3,)).astype(np.int64)

    @property
    def voronoi(self) -> np.ndarray:
        return self._joined(lambda rod, a: a.voronoi, ())

    @property
    def EI(self) -> np.ndarray:
        return self._joined(lambda rod, a: a.EI, ())

    @property
    def EI2(self) -> np.ndarray:
        return self._joined(lambda rod, a: a.EI2, ())

    @property
    def GJ(self) -> np.ndarray:
        return self._joined(lambda rod, a: a.GJ, ())

    @property
    def natural_curvature(self) -> np.ndarray:
        return self._joined(lambda rod, a: a.natural_curvature, (2, 2))

    @property
    def natural_twist(self) -> np.ndarray:
        return self._joined(lambda rod, a: a.natural_twist, ())

    def edge_sections(self):
        """Section data of every edge for the extreme-fibre stress, or None when no rod has a section shape.

        Edges of rods without a shape hold NaN.
        """
        from ..effects.rod_output import EdgeSections

        if not any(a.shape is not None for a in self._arrays):
            return None

        def per_edge(value):
            return self._joined(lambda rod, a: np.full(len(a.edge_nodes), np.nan if a.shape is None else value(a.shape)), ())

        return EdgeSections(
            area=per_edge(lambda sh: sh.area), inv_modulus_1=per_edge(lambda sh: sh.c1 / sh.I1),
            inv_modulus_2=per_edge(lambda sh: sh.c2 / sh.I2),
            round=self._joined(lambda rod, a: np.full(len(a.edge_nodes), a.shape is not None and a.shape.round), (),
                               bool),
            EA=self.EA, rest_length=self.rest_length,
        )

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
                s.n_nodes, self.edges, self.hinge_edges, s.reference_state(),
                self._joined(lambda rod, a: a.director, (3,)),
            )
        return self._frames

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
        if self._anchor_held:
            self.frames.anchor(self.structure.constrained_mask[self.edge_twist])
        out = [RodStretching(n_dof, self.edges, self.EA, self.rest_length)]
        if self._n_hinges:
            stencil = self.hinge_stencils()
            out.append(RodBending(n_dof, self.frames, stencil, self.voronoi, self.EI, self.natural_curvature,
                                  EI2=self.EI2, sections=self.edge_sections()))
            out.append(RodTwisting(n_dof, self.frames, stencil, self.voronoi, self.GJ, self.natural_twist))
        if len(self.joints):
            out.append(PenaltyJoints(n_dof, self.joints, self.joint_stiffness))
        if self._crossing_stiffness > 0:
            from ..effects.joint_rotation import JointRotation
            from .crossings import crossing_chords

            ends = crossing_chords(self)
            if len(ends):
                out.append(JointRotation(n_dof, ends, self._crossing_stiffness, self.structure.reference_state()))
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
    from ..effects.sliding import sliding_effects

    effects += sliding_effects(s) + nodal_load_effects(s)
    if s.gravity is not None:
        effects.append(gravity_effect(s, scales_with_load=gravity_scaled))
    effects += list(extra_effects)
    if check:
        network.check_supports()
    return System(s, effects, check=False)
