"""The structural model: nodes, degrees of freedom, member groups, supports and loads.

A :class:`Structure` is a plain description of what is built; it knows nothing
about how it is solved. Degrees of freedom live in one flat vector ``q``: three
translations per node (``q[3 i : 3 i + 3]`` is node ``i``), followed by one twist
angle per rod edge that asks for one (``q[3 n_nodes + k]``).

Every ``add_*`` method validates its input immediately, so a bad index, a NaN
coordinate or a zero-length member is reported where it was introduced, with
the member group and the member number in the message.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from .errors import MechanismError, ModelError

if TYPE_CHECKING:
    from .geometry.space_curve import SpaceCurve

AXES = {"x": 0, "y": 1, "z": 2}
STANDARD_GRAVITY = (0.0, 0.0, -9.81)
#: largest coordinate magnitude [m]: beyond it double precision leaves no digits for member lengths
#: (a scene is held to 1e6 m, see :data:`shellform.scene.schema.UNIT_BOUNDS`)
MAX_COORDINATE = 1.0e12


#: what a node slides on
SLIDE_KINDS = ("plane", "line")
#: spring across a sliding support's plane or line, as a multiple of the stiffest member at the node
SLIDE_STIFFNESS_RATIO = 1.0e2


@dataclass(frozen=True)
class Slider:
    """Nodes that slide on a plane or along a line: the projector onto the directions they are held in, a
    point of each node's plane or line (None: the node's reference position), and the springs' stiffness
    (None: ``stiffness_ratio`` times the stiffest member at each node)."""

    nodes: np.ndarray
    held: np.ndarray
    stiffness_ratio: float
    origin: np.ndarray | None = None
    stiffness: np.ndarray | None = None


@dataclass(frozen=True)
class CurveSlider:
    """Nodes that slide along one curve: the curve's shift per node (so that it passes through the node's
    reference position), and the springs' stiffness (None: ``stiffness_ratio`` times the stiffest member at
    each node)."""

    nodes: np.ndarray
    curve: SpaceCurve
    shift: np.ndarray
    stiffness_ratio: float
    stiffness: np.ndarray | None = None


@dataclass(frozen=True)
class MemberGroup:
    """A set of two-node members sharing one constitutive law.

    Attributes
    ----------
    name : str
        Group name used in messages and output.
    kind : {"bar", "rope"}
        ``"bar"`` carries tension and compression; ``"rope"`` only tension.
    connectivity : ndarray, shape (m, 2)
        Node indices of each member.
    EA : ndarray, shape (m,)
        Axial stiffness [N].
    rest_length : ndarray, shape (m,)
        Unstressed length [m].
    mass_per_length : ndarray, shape (m,)
        Linear density [kg/m], lumped half to each end node for self-weight.
    """

    name: str
    kind: str
    connectivity: np.ndarray
    EA: np.ndarray
    rest_length: np.ndarray
    mass_per_length: np.ndarray

    @property
    def n_members(self) -> int:
        return len(self.connectivity)


@dataclass(frozen=True)
class LoadCase:
    """Nodal forces [N] on the translational DOFs.

    ``scaled`` loads are multiplied by the load factor of the analysis; the
    others (dead loads) are always applied in full.
    """

    forces: np.ndarray  # shape (n_nodes, 3)
    scaled: bool = True


def _as_index_array(values, n_max: int, what: str) -> np.ndarray:
    arr = np.asarray(values)
    if arr.size == 0:
        return arr.astype(np.int64).reshape(arr.shape)
    if not np.issubdtype(arr.dtype, np.integer):
        if np.issubdtype(arr.dtype, np.floating) and np.all(np.isfinite(arr)) and np.all(arr == np.round(arr)):
            arr = arr.astype(np.int64)
        else:
            raise ModelError(f"{what}: node indices must be integers, got {arr.dtype} values")
    arr = arr.astype(np.int64)
    bad = np.flatnonzero((arr < 0) | (arr >= n_max))
    if bad.size:
        flat = arr.ravel()
        raise ModelError(
            f"{what}: node index {int(flat[bad[0]])} is out of range "
            f"(the model has {n_max} nodes, valid indices 0..{n_max - 1})"
        )
    return arr


def broadcast_property(value, m: int, what: str, allow_zero: bool = False, item: str = "member") -> np.ndarray:
    """A scalar or ``m`` per-item values as a checked float array of shape ``(m,)``.

    Raises :class:`ModelError` naming ``what`` and the first offending
    ``item`` (member, edge, hinge, joint, entry) when the shape is wrong or a value is
    not finite or not positive (non-negative with ``allow_zero``).
    """
    arr = np.asarray(value, dtype=float)
    if arr.ndim == 0:
        arr = np.full(m, float(arr))
    if arr.shape != (m,):
        raise ModelError(f"{what}: expected a scalar or {m} values, got shape {arr.shape}")
    bad = np.flatnonzero(~np.isfinite(arr))
    if bad.size:
        raise ModelError(f"{what}: value of {item} {int(bad[0])} is not finite ({arr[bad[0]]})")
    bad = np.flatnonzero(arr < 0 if allow_zero else arr <= 0)
    if bad.size:
        need = "non-negative" if allow_zero else "positive"
        raise ModelError(f"{what}: value of {item} {int(bad[0])} must be {need}, got {arr[bad[0]]}")
    return arr


def parse_dofs(dofs: str, what: str = "dofs") -> list[int]:
    """Translate a string such as ``"xz"`` into translational components ``[0, 2]``."""
    if not isinstance(dofs, str) or not dofs or any(c not in AXES for c in dofs.lower()):
        raise ModelError(f"{what}: expected a combination of the letters x, y, z, got {dofs!r}")
    return sorted({AXES[c] for c in dofs.lower()})


class Structure:
    """Nodes, members, supports and loads of a 1D-member structure.

    Parameters
    ----------
    nodes : array_like, shape (n, 3)
        Reference coordinates [m]. Every entry must be finite.

    Examples
    --------
    >>> s = Structure([[0, 0, 0], [1, 0, 1], [2, 0, 0]])
    >>> s.add_bars([[0, 1], [1, 2]], EA=1e6)
    >>> s.fix([0, 2])
    >>> s.fix([1], "y")
    >>> s.add_load([1], [0, 0, -100.0])
    """

    def __init__(self, nodes):
        nodes = np.asarray(nodes, dtype=float)
        if nodes.ndim != 2 or nodes.shape[1] != 3 or nodes.shape[0] == 0:
            raise ModelError(f"nodes: expected an array of shape (n, 3) with n >= 1, got shape {nodes.shape}")
        bad = np.argwhere(~np.isfinite(nodes))
        if bad.size:
            i, c = bad[0]
            raise ModelError(f"nodes: coordinate {'xyz'[c]} of node {i} is not finite ({nodes[i, c]})")
        bad = np.argwhere(np.abs(nodes) > MAX_COORDINATE)
        if bad.size:
            i, c = bad[0]
            raise ModelError(f"nodes: coordinate {'xyz'[c]} of node {i} is {nodes[i, c]:.3g}; magnitudes beyond "
                             f"{MAX_COORDINATE:.0e} m leave no digits for member lengths (is a unit off?)")
        self.nodes = nodes
        self.groups: list[MemberGroup] = []
        self.n_twist = 0
        # per-DOF constraint flags; grown by add_twist_dofs
        self._fixed = np.zeros(3 * len(nodes), dtype=bool)
        self._prescribed = np.zeros(3 * len(nodes))  # displacement per unit parameter
        self._is_prescribed = np.zeros(3 * len(nodes), dtype=bool)
        self.load_cases: list[LoadCase] = []
        self.point_mass = np.zeros(len(nodes))
        self.gravity: np.ndarray | None = None
        self.sliders: list[Slider] = []
        self.curve_sliders: list[CurveSlider] = []

    # -- sizes and numbering -------------------------------------------------
    @property
    def n_nodes(self) -> int:
        return len(self.nodes)

    @property
    def n_dof(self) -> int:
        """Total number of DOFs: 3 per node plus the twist angles."""
        return 3 * self.n_nodes + self.n_twist

    def node_dofs(self, nodes) -> np.ndarray:
        """DOF indices of the translations of ``nodes``, shape ``(len(nodes), 3)``."""
        nodes = np.asarray(nodes, dtype=np.int64)
        return 3 * nodes[..., None] + np.arange(3)

    def add_twist_dofs(self, count: int) -> np.ndarray:
        """Append ``count`` twist-angle DOFs (one per rod edge) and return their indices."""
        count = int(count)
        if count < 0:
            raise ModelError(f"twist DOFs: count must be non-negative, got {count}")
        start = self.n_dof
        self.n_twist += count
        self._fixed = np.concatenate([self._fixed, np.zeros(count, dtype=bool)])
        self._prescribed = np.concatenate([self._prescribed, np.zeros(count)])
        self._is_prescribed = np.concatenate([self._is_prescribed, np.zeros(count, dtype=bool)])
        return np.arange(start, start + count)

    def fix_dofs(self, dofs) -> None:
        """Fix arbitrary DOFs (by flat index) at their reference value."""
        dofs = np.atleast_1d(np.asarray(dofs))
        if dofs.size and (not np.issubdtype(dofs.dtype, np.integer) or dofs.min() < 0 or dofs.max() >= self.n_dof):
            raise ModelError(f"support: DOF indices must be integers in 0..{self.n_dof - 1}, got {dofs}")
        self._fixed[dofs] = True

    def prescribe_dofs(self, dofs, direction) -> None:
        """Prescribe arbitrary DOFs (by flat index): value = reference + parameter * direction."""
        dofs = np.atleast_1d(np.asarray(dofs))
        if dofs.size and (not np.issubdtype(dofs.dtype, np.integer) or dofs.min() < 0 or dofs.max() >= self.n_dof):
            raise ModelError(f"prescribed displacement: DOF indices must be integers in 0..{self.n_dof - 1}, got {dofs}")
        d = np.broadcast_to(np.asarray(direction, dtype=float), dofs.shape)
        if not np.all(np.isfinite(d)):
            raise ModelError("prescribed displacement: direction must be finite")
        self._is_prescribed[dofs] = True
        self._prescribed[dofs] = d

    def reference_state(self) -> np.ndarray:
        """The DOF vector of the reference configuration (twist angles zero)."""
        return np.concatenate([self.nodes.ravel(), np.zeros(self.n_twist)])

    @property
    def members(self) -> list[MemberGroup]:
        return list(self.groups)

    def group(self, name: str) -> MemberGroup:
        for g in self.groups:
            if g.name == name:
                return g
        raise KeyError(f"no member group named {name!r}; groups are {[g.name for g in self.groups]}")

    # -- members ---------------------------------------------------------------
    def _add_group(self, kind, connectivity, EA, rest_length, mass_per_length, name) -> MemberGroup:
        name = name or f"{kind}s{len(self.groups)}"
        if any(g.name == name for g in self.groups):
            raise ModelError(f"member group {name!r}: a group with this name already exists")
        conn = np.asarray(connectivity)
        if conn.ndim != 2 or conn.shape[1] != 2:
            raise ModelError(f"member group {name!r}: connectivity must have shape (m, 2), got {conn.shape}")
        conn = _as_index_array(conn, self.n_nodes, f"member group {name!r}")
        m = len(conn)
        same = np.flatnonzero(conn[:, 0] == conn[:, 1])
        if same.size:
            k = int(same[0])
            raise ModelError(f"member group {name!r}: member {k} connects node {conn[k, 0]} to itself")
        length = np.linalg.norm(self.nodes[conn[:, 1]] - self.nodes[conn[:, 0]], axis=1)
        scale = max(float(np.ptp(self.nodes, axis=0).max()), 1.0)
        short = np.flatnonzero(length <= 1e-12 * scale)
        if short.size and rest_length is None:
            k = int(short[0])
            raise ModelError(
                f"member group {name!r}: member {k} (nodes {conn[k, 0]}-{conn[k, 1]}) has zero length; "
                "coincident nodes cannot define a member"
            )
        rest = length if rest_length is None else rest_length
        rest = broadcast_property(rest, m, f"member group {name!r} rest_length")
        group = MemberGroup(
            name=name,
            kind=kind,
            connectivity=conn,
            EA=broadcast_property(EA, m, f"member group {name!r} EA"),
            rest_length=rest,
            mass_per_length=broadcast_property(mass_per_length, m, f"member group {name!r} mass_per_length", True),
        )
        self.groups.append(group)
        return group

    def add_bars(self, connectivity, EA, mass_per_length=0.0, rest_length=None, name: str | None = None) -> MemberGroup:
        """Add elastic bars (tension and compression).

        The rest length defaults to the distance between the nodes in the
        reference configuration.
        """
        return self._add_group("bar", connectivity, EA, rest_length, mass_per_length, name)

    def add_ropes(
        self, connectivity, EA, slack=0.0, mass_per_length=0.0, rest_length=None, name: str | None = None
    ) -> MemberGroup:
        """Add tension-only ropes.

        Parameters
        ----------
        slack : float or array_like
            Slack coefficient ``sc``: the rope's rest length is ``(1 + sc)``
            times the reference distance between its nodes (MRA, Eqs. 3-4).
            Ignored where ``rest_length`` is given.
        """
        conn = np.asarray(connectivity)
        if rest_length is None:
            sc = np.asarray(slack, dtype=float)
            if not np.all(np.isfinite(sc)) or np.any(sc <= -1.0):
                raise ModelError(f"rope group {name!r}: slack coefficient must be finite and > -1, got {slack}")
            if conn.ndim == 2 and conn.shape[1] == 2:
                c = _as_index_array(conn, self.n_nodes, f"rope group {name!r}")
                dist = np.linalg.norm(self.nodes[c[:, 1]] - self.nodes[c[:, 0]], axis=1)
                scale = max(float(np.ptp(self.nodes, axis=0).max()), 1.0)
                short = np.flatnonzero(dist <= 1e-12 * scale)
                if short.size:
                    k = int(short[0])
                    raise ModelError(
                        f"rope group {name!r}: member {k} (nodes {c[k, 0]}-{c[k, 1]}) has zero length; "
                        "coincident nodes cannot define a member"
                    )
                rest_length = (1.0 + sc) * dist
        return self._add_group("rope", conn, EA, rest_length, mass_per_length, name)

    # -- supports and prescribed motion ----------------------------------------
    def fix(self, nodes, dofs: str = "xyz") -> None:
        """Fix the listed translational components of ``nodes`` at their reference position."""
        nodes = _as_index_array(np.atleast_1d(nodes), self.n_nodes, "support")
        comps = parse_dofs(dofs, "support dofs")
        self._fixed[self.node_dofs(nodes)[:, comps].ravel()] = True

    def slide(self, nodes, kind: str, direction, stiffness_ratio: float = SLIDE_STIFFNESS_RATIO) -> None:
        """Let ``nodes`` slide on a plane (``kind = "plane"``, ``direction`` its normal) or along a line
        (``"line"``, ``direction`` the line's) through their reference positions, of any direction.

        Held by stiff springs across the plane or line
        (:class:`~shellform.effects.sliding.SlidingSupports`), ``stiffness_ratio``
        times the stiffest member at each node when the system is built.
        """
        nodes = _as_index_array(np.atleast_1d(nodes), self.n_nodes, "sliding support")
        if kind not in SLIDE_KINDS:
            raise ModelError(f"sliding support: kind must be one of {SLIDE_KINDS}, got {kind!r}")
        d = np.asarray(direction, dtype=float)
        if d.shape != (3,) or not np.all(np.isfinite(d)) or np.linalg.norm(d) == 0:
            raise ModelError(f"sliding support: direction must be a non-zero finite [x, y, z], got {direction!r}")
        if not (np.isfinite(stiffness_ratio) and stiffness_ratio > 0):
            raise ModelError(f"sliding support: stiffness_ratio must be a positive number, got {stiffness_ratio!r}")
        d = d / np.linalg.norm(d)
        held = np.outer(d, d) if kind == "plane" else np.eye(3) - np.outer(d, d)
        self.sliders.append(Slider(nodes, held, float(stiffness_ratio)))

    def slide_along(self, nodes, curve, stiffness_ratio: float = SLIDE_STIFFNESS_RATIO,
                    tolerance: float | None = None) -> None:
        """Let ``nodes`` slide along ``curve`` (a :class:`~shellform.geometry.space_curve.SpaceCurve`, or points
        it passes through), an arch or a ring beam.

        Held by stiff springs to the curve's nearest point
        (:class:`~shellform.effects.curve_sliding.CurveSupports`), ``stiffness_ratio`` times the stiffest
        member at each node when the system is built. Every node must lie on the curve, within
        ``tolerance`` (default 1e-6 times the structure's size, at least 1e-6 m); the curve is then moved
        by that little so that it passes through the node exactly, as a plane or line does.
        """
        from .geometry.space_curve import SpaceCurve

        nodes = _as_index_array(np.atleast_1d(nodes), self.n_nodes, "sliding support")
        if not isinstance(curve, SpaceCurve):
            curve = SpaceCurve.through(curve, "sliding support curve")
        if not (np.isfinite(stiffness_ratio) and stiffness_ratio > 0):
            raise ModelError(f"sliding support: stiffness_ratio must be a positive number, got {stiffness_ratio!r}")
        x = self.nodes[nodes]
        t, _ = curve.nearest(x)
        shift = x - curve(t)
        if tolerance is None:
            tolerance = 1e-6 * max(float(np.ptp(self.nodes, axis=0).max()), 1.0)
        far = np.linalg.norm(shift, axis=1)
        if far.max() > tolerance:
            k = int(np.argmax(far))
            raise ModelError(f"sliding support: node {int(nodes[k])} at {np.round(x[k], 6).tolist()} is "
                             f"{far[k]:.4g} m from its curve (tolerance {tolerance:.3g} m); give the curve through "
                             "the points the nodes lie on, or a larger tolerance")
        self.curve_sliders.append(CurveSlider(nodes, curve, shift, float(stiffness_ratio)))

    def prescribe(self, nodes, direction) -> None:
        """Prescribe the motion of ``nodes``: displacement = ``parameter * direction``.

        ``direction`` has shape (3,) or (len(nodes), 3). All three components
        are constrained (a zero component holds that coordinate fixed).
        """
        nodes = _as_index_array(np.atleast_1d(nodes), self.n_nodes, "prescribed displacement")
        d = np.broadcast_to(np.asarray(direction, dtype=float), (len(nodes), 3))
        if not np.all(np.isfinite(d)):
            raise ModelError("prescribed displacement: direction must be finite")
        self.prescribe_dofs(self.node_dofs(nodes).ravel(), d.ravel())

    # -- loads and mass --------------------------------------------------------
    def add_load(self, nodes, force, scaled: bool = True) -> None:
        """Add nodal forces [N]. ``force`` has shape (3,) or (len(nodes), 3)."""
        nodes = _as_index_array(np.atleast_1d(nodes), self.n_nodes, "load")
        f = np.asarray(force, dtype=float)
        try:
            f = np.broadcast_to(f, (len(nodes), 3))
        except ValueError:
            raise ModelError(f"load: force must have shape (3,) or ({len(nodes)}, 3), got {f.shape}") from None
        if not np.all(np.isfinite(f)):
            raise ModelError("load: force components must be finite")
        forces = np.zeros((self.n_nodes, 3))
        np.add.at(forces, nodes, f)
        self.load_cases.append(LoadCase(forces=forces, scaled=scaled))

    def add_point_mass(self, nodes, mass) -> None:
        """Add lumped masses [kg] at nodes (they take part in self-weight and dynamics)."""
        nodes = _as_index_array(np.atleast_1d(nodes), self.n_nodes, "point mass")
        m = np.broadcast_to(np.asarray(mass, dtype=float), nodes.shape)
        if not np.all(np.isfinite(m)) or np.any(m < 0):
            raise ModelError("point mass: masses must be finite and non-negative")
        np.add.at(self.point_mass, nodes, m)

    def set_gravity(self, g=STANDARD_GRAVITY) -> None:
        """Apply self-weight of the member and point masses with acceleration ``g`` [m/s^2]."""
        g = np.asarray(g, dtype=float)
        if g.shape != (3,) or not np.all(np.isfinite(g)):
            raise ModelError(f"gravity: expected 3 finite components, got {g}")
        self.gravity = g

    def nodal_mass(self) -> np.ndarray:
        """Lumped nodal masses [kg]: half of each member's mass to each end, plus point masses."""
        m = self.point_mass.copy()
        for g in self.groups:
            half = 0.5 * g.mass_per_length * g.rest_length
            m += np.bincount(g.connectivity[:, 0], half, minlength=self.n_nodes)
            m += np.bincount(g.connectivity[:, 1], half, minlength=self.n_nodes)
        return m

    # -- DOF partition -------------------------------------------------------------
    @property
    def fixed_dofs(self) -> np.ndarray:
        """DOFs held at their reference value."""
        return np.flatnonzero(self._fixed & ~self._is_prescribed)

    @property
    def prescribed_dofs(self) -> np.ndarray:
        """DOFs moved by the prescribed-displacement parameter."""
        return np.flatnonzero(self._is_prescribed)

    @property
    def prescribed_direction(self) -> np.ndarray:
        """Displacement of every DOF per unit prescribed parameter (zero where not prescribed)."""
        return np.where(self._is_prescribed, self._prescribed, 0.0)

    @property
    def constrained_mask(self) -> np.ndarray:
        """True for every fixed or prescribed DOF."""
        return self._fixed | self._is_prescribed

    def check_supports(self) -> None:
        """Raise :class:`MechanismError` if a connected part can translate freely.

        Each connected part of the member graph must have its three rigid
        translations restrained by supports or prescribed DOFs. Rotations are
        not required to be restrained: a part hanging from one point is a
        pendulum that loads stabilise through geometric stiffness.
        """
        from scipy.sparse import coo_matrix
        from scipy.sparse.csgraph import connected_components

        n = self.n_nodes
        if self.groups:
            conn = np.concatenate([g.connectivity for g in self.groups])
        else:
            conn = np.zeros((0, 2), dtype=np.int64)
        adj = coo_matrix((np.ones(len(conn)), (conn[:, 0], conn[:, 1])), shape=(n, n))
        n_comp, label = connected_components(adj, directed=False)
        cons = self.constrained_mask[: 3 * n].reshape(n, 3)
        # a translation along axis c of a component is restrained iff some node of
        # that component has component c constrained; axis-wise is exact because
        # supports act on Cartesian components.
        restrained = np.zeros((n_comp, 3), dtype=bool)
        for c in range(3):
            restrained[:, c] = np.bincount(label, cons[:, c].astype(float), minlength=n_comp) > 0
        bad = np.argwhere(~restrained)
        if bad.size:
            comp, axis = bad[0]
            members = np.flatnonzero(label == comp)
            listed = ", ".join(str(i) for i in members[:8]) + (", ..." if len(members) > 8 else "")
            if len(members) == 1:
                what = f"node {members[0]} (not attached to any member)"
            else:
                what = f"the connected part with nodes {listed} ({len(members)} nodes)"
            raise MechanismError(
                f"the structure is a mechanism: {what} can translate freely along {'xyz'[axis]}; "
                f"add a support restraining {'xyz'[axis]} on it"
            )
