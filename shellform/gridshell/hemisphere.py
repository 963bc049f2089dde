"""The pre-stressed hemispherical gridshell of discrete elastic rods.

The rods are straight when unstressed and are laid out as a square grid in the
plane; bent onto the Chebyshev net of the hemisphere
(:func:`shellform.geometry.chebyshev.chebyshev_hemisphere`) they keep the
distance ``h`` between joints along every rod. Each inter-joint segment is
cut into ``round(h / dl)`` edges (``dl`` the Voronoi length), so every joint is
a rod node and all edges of a segment have the same rest length.

Two ways to reach the pre-stressed hemisphere are offered:

* :func:`prestress_by_paths` (the paper's route): the model starts flat (a
  small upward bump chooses the buckling direction), the pinned rod ends are
  moved along straight paths in the plane from their footprint to the
  equator, and the structure is relaxed in load steps.
* :func:`prestress_on_net` (the cheaper route): the model starts on the net
  itself, with the rest lengths of the planar rods, and one static Newton
  solve relaxes it. The net is already nearly in equilibrium: on a sphere the
  geodesic torsion of every curve vanishes, so rods with their first director
  along the surface normal carry it along as the normal without twist, which
  is exactly how a flat strip bends onto the sphere.

Both give the same equilibrium (see :func:`compare_shapes`).

Units are SI; the paper's defaults are in :data:`PAPER`.
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass, field, replace

import numpy as np

from ..assembly import System
from ..errors import ModelError
from ..geometry.chebyshev import ChebyshevHemisphere, chebyshev_hemisphere
from ..model import Structure
from ..rods.network import RodNetwork, build_rod_system
from ..rods.node_path import NodePath
from ..rods.section import RestShape, RodSection, circular_section
from ..rods.statics import solve_incremental
from ..solvers.newton import solve_static
from .layout import NodeLayout, lay_out_nodes

#: parameters of the gridshell paper (Huang, Qin, Chen, J. Appl. Mech. 89(1) 011005, 2022, DOI 10.1115/1.4052289)
PAPER = dict(
    radius=0.0764 / 2.0,
    rod_radius=1.0e-3,
    youngs_modulus=100.0e9,
    density=1000.0,
    voronoi_length=1.0e-3,
)


@dataclass
class HemisphereModel:
    """A hemispherical gridshell model: geometry, structure, rods and the nodes that matter.

    Attributes
    ----------
    net : ChebyshevHemisphere
        The Chebyshev net (rod geometry on the sphere and in the plane).
    structure : Structure
    network : RodNetwork
    configuration : {"sphere", "plane"}
        Where the reference nodes sit: on the net, or in the flat footprint.
    rod_nodes : list of ndarray
        Node indices along each rod, in the order of ``net.rods``.
    rod_stations : list of ndarray
        Arc-length coordinate of every node along its rod (the planar position).
    joint_nodes : ndarray (k, 2)
        For every joint, the node on its u rod and on its v rod (equal for shared joints).
    joint_keys : list of (int, int)
        ``(u_index, v_index)`` of every joint.
    end_nodes : ndarray (2n, 2)
        First and last node of every rod (pinned on the equator).
    sphere_nodes, plane_nodes : ndarray (n_nodes, 3)
        Node positions on the net and in the flat footprint.
    equator_ends : ndarray (2n, 2, 3)
        Positions of the rod ends on the equator.
    EI : float
        Bending stiffness of a rod [N m^2].
    params : dict
        The parameters the model was built with.
    """

    net: ChebyshevHemisphere
    structure: Structure
    network: RodNetwork
    configuration: str
    rod_nodes: list
    rod_stations: list
    joint_nodes: np.ndarray
    joint_keys: list
    end_nodes: np.ndarray
    sphere_nodes: np.ndarray
    plane_nodes: np.ndarray
    equator_ends: np.ndarray
    EI: float
    params: dict = field(default_factory=dict)
    paths: list = field(default_factory=list)

    @property
    def radius(self) -> float:
        return self.net.radius

    @property
    def n(self) -> int:
        return self.net.n

    def rod_index(self, family: str, index: int) -> int:
        for k, r in enumerate(self.net.rods):
            if r.family == family and r.index == index:
                return k
        raise ModelError(f"hemisphere: no rod {family}{index}")

    def joint(self, u_index: int, v_index: int) -> np.ndarray:
        """Node(s) of a joint: ``[node on u rod, node on v rod]``."""
        for key, nodes in zip(self.joint_keys, self.joint_nodes):
            if key == (u_index, v_index):
                return nodes
        raise ModelError(f"hemisphere: no joint ({u_index}, {v_index})")

    @property
    def apex_nodes(self) -> np.ndarray:
        """The apex joint's node(s): two coincident nodes for penalty joints, one when shared."""
        return np.unique(self.joint(0, 0))

    def apex_neighbours(self) -> np.ndarray:
        """The nodes next to the apex along the two central rods (four nodes)."""
        out = []
        for family, node in zip(("u", "v"), self.joint(0, 0)):
            k = self.rod_index(family, 0)
            nodes = self.rod_nodes[k]
            i = int(np.flatnonzero(nodes == node)[0])
            out += [nodes[i - 1], nodes[i + 1]]
        return np.array(out, dtype=np.int64)

    @property
    def n_dof(self) -> int:
        return self.structure.n_dof

    def positions(self, q: np.ndarray) -> np.ndarray:
        """Node coordinates ``(n_nodes, 3)`` of a state."""
        return np.asarray(q)[: 3 * self.structure.n_nodes].reshape(-1, 3)

    def mirror_map(self, axis: int) -> np.ndarray:
        """Node permutation of the net's reflection ``x[axis] -> -x[axis]`` (``axis`` 0 or 1).

        Node ``i`` of the reflected state is node ``mirror_map(axis)[i]`` of the
        original, on a rod of the same family (coincident penalty-joint nodes
        are told apart by their rod).
        """
        from scipy.spatial import cKDTree

        cache = self.__dict__.setdefault("_mirror_cache", {})
        if axis not in cache:
            family = np.zeros(self.structure.n_nodes, dtype=np.int64)
            for rod, idx in zip(self.net.rods, self.rod_nodes):
                if rod.family == "v":
                    family[idx] = 1
            x = self.sphere_nodes
            y = x.copy()
            y[:, axis] *= -1.0
            d, cand = cKDTree(x).query(y, k=2)
            same = family[cand[:, 1]] == family
            pick = np.where((d[:, 1] <= d[:, 0] + 1e-9 * self.radius) & same & (family[cand[:, 0]] != family),
                            cand[:, 1], cand[:, 0])
            if np.max(np.linalg.norm(x[pick] - y, axis=1)) > 1e-6 * self.radius:
                raise ModelError("hemisphere: the net is not mirror symmetric")
            cache[axis] = pick
        return cache[axis]

    def rod_polylines(self, q: np.ndarray) -> list[np.ndarray]:
        """Every rod's centreline at state ``q`` (list of ``(N_k, 3)`` arrays)."""
        x = self.positions(q)
        return [x[idx] for idx in self.rod_nodes]


@dataclass(frozen=True)
class HemisphereSpec:
    """What a hemispherical gridshell is made of: its net, the rods' section, the joints and the start.

    Attributes
    ----------
    n : int
        Rods per direction (odd); ``2 n`` rods in all.
    radius : float
        Hemisphere radius R [m] (paper: 2R = 7.64 cm).
    voronoi_length : float
        Target edge length ``dl`` [m]; each inter-joint segment gets ``round(h / dl)`` edges.
    rod_radius, youngs_modulus, density : float
        Circular section ``r0``, ``E``, ``rho``.
    shear_modulus : float, optional
        Default ``E / 3`` (incompressible material, as in the paper).
    joints : {"penalty", "shared"}
        Two coincident nodes tied by the penalty spring of the paper (Eq. 3),
        or one node shared by both rods.
    stiffness_ratio : float
        Penalty stiffness relative to the rods' axial stiffness at the joint.
    configuration : {"sphere", "plane"}
        Reference nodes on the net (for :func:`prestress_on_net`) or in the
        flat footprint (for :func:`prestress_by_paths`).
    bump : float
        Only for ``"plane"``: height of the initial upward bump, as a
        fraction of ``R``, that makes the flat grid buckle upwards.
    """

    n: int
    radius: float = PAPER["radius"]
    voronoi_length: float = PAPER["voronoi_length"]
    rod_radius: float = PAPER["rod_radius"]
    youngs_modulus: float = PAPER["youngs_modulus"]
    shear_modulus: float | None = None
    density: float = PAPER["density"]
    joints: str = "penalty"
    stiffness_ratio: float = 1.0e3
    configuration: str = "sphere"
    bump: float = 0.05


def _checked(spec: HemisphereSpec) -> HemisphereSpec:
    """The spec with its values checked, as floats, and the shear modulus filled in."""
    if spec.joints not in ("penalty", "shared"):
        raise ModelError(f"hemisphere: joints must be 'penalty' or 'shared', got {spec.joints!r}")
    if spec.configuration not in ("sphere", "plane"):
        raise ModelError(f"hemisphere: configuration must be 'sphere' or 'plane', got {spec.configuration!r}")
    for what in ("radius", "voronoi_length", "rod_radius", "youngs_modulus"):
        v = getattr(spec, what)
        if not (np.isfinite(v) and v > 0):
            raise ModelError(f"hemisphere: {what} must be positive and finite, got {v}")
    G = spec.youngs_modulus / 3.0 if spec.shear_modulus is None else spec.shear_modulus
    return replace(
        spec, radius=float(spec.radius), voronoi_length=float(spec.voronoi_length),
        rod_radius=float(spec.rod_radius), youngs_modulus=float(spec.youngs_modulus), shear_modulus=float(G),
        density=float(spec.density), stiffness_ratio=float(spec.stiffness_ratio), bump=float(spec.bump),
    )


def _reference_nodes(spec: HemisphereSpec, layout: NodeLayout) -> np.ndarray:
    """The nodes on the net, or in the footprint raised by a small bump (so the flat grid buckles upwards)."""
    if spec.configuration == "sphere":
        return layout.sphere_nodes.copy()
    plane = layout.plane_nodes
    ref = plane.copy()
    rmax = max(float(np.linalg.norm(plane[:, :2], axis=1).max()), 1e-300)
    rr = np.linalg.norm(plane[:, :2], axis=1) / rmax
    ref[:, 2] = spec.bump * spec.radius * (1.0 - rr**2)
    return ref


def _rod_network(spec: HemisphereSpec, net: ChebyshevHemisphere, layout: NodeLayout,
                 section: RodSection) -> RodNetwork:
    """Straight rods along the net's lines, joined at the joints and pinned at both ends."""
    network = RodNetwork(Structure(_reference_nodes(spec, layout)))
    on_net = spec.configuration == "sphere"
    for rod, idx, s in zip(net.rods, layout.rod_nodes, layout.stations):
        # on the net the first director is the surface normal, which the rod carries without twist
        first = layout.sphere_nodes[idx[0]] / spec.radius if on_net else np.array([0.0, 0.0, 1.0])
        rest = RestShape(natural_curvature="straight", rest_length=np.diff(s), director=first)
        network.add_rod(idx, section, rest, name=f"{rod.family}{rod.index:+d}")
    if spec.joints == "penalty":
        network.add_joints(layout.joint_nodes, stiffness_ratio=spec.stiffness_ratio)
    for k in range(len(net.rods)):
        network.pin(k, "start", twist="fixed")
        network.pin(k, "end", twist="fixed")
    return network


def build_hemisphere(spec: HemisphereSpec) -> HemisphereModel:
    """The rod network of the hemispherical gridshell that ``spec`` describes.

    Returns
    -------
    HemisphereModel
        Rod ends pinned (translations fixed, end twist fixed). In the
        ``"plane"`` configuration the end translations follow the paths in
        ``model.paths`` (footprint at ``t = 0``, equator at ``t = 1``).
    """
    spec = _checked(spec)
    net = chebyshev_hemisphere(spec.radius, spec.n)
    if spec.voronoi_length > net.spacing:
        raise ModelError(f"hemisphere: voronoi_length {spec.voronoi_length} exceeds the joint spacing "
                         f"{net.spacing:.4g}")
    section = circular_section(spec.youngs_modulus, spec.shear_modulus, spec.rod_radius, spec.density)
    layout = lay_out_nodes(net, spec.voronoi_length, shared=spec.joints == "shared")
    network = _rod_network(spec, net, layout, section)
    end_nodes = layout.end_nodes
    equator = np.array(net.equator_ends())
    paths = []
    if spec.configuration == "plane":
        start = layout.plane_nodes[end_nodes.ravel()]
        paths.append(NodePath.waypoints(network.structure, end_nodes.ravel(), [0.0, 1.0],
                                        [start, equator.reshape(-1, 3)]))
    return HemisphereModel(
        net=net, structure=network.structure, network=network, configuration=spec.configuration,
        rod_nodes=[np.asarray(i, dtype=np.int64) for i in layout.rod_nodes], rod_stations=layout.stations,
        joint_nodes=layout.joint_nodes, joint_keys=layout.joint_keys, end_nodes=end_nodes,
        sphere_nodes=layout.sphere_nodes, plane_nodes=layout.plane_nodes, equator_ends=equator,
        EI=float(section.EI), params={**asdict(spec), "n": int(spec.n)}, paths=paths,
    )


@dataclass
class PrestressResult:
    """A pre-stressed hemisphere.

    Attributes
    ----------
    q : ndarray
        Equilibrium state (ends on the equator).
    system : System
        The system the state was found with (apex free).
    success : bool
    message : str
    steps, iterations : int
        Load steps and total Newton iterations.
    wall_time_s : float
    frames : dict
        The rods' reference frames at ``q`` (:meth:`ReferenceFrames.state`):
        the twist angles in ``q`` are measured from them, so any later
        analysis starting from ``q`` restores them first.
    """

    q: np.ndarray
    system: System
    success: bool
    message: str
    steps: int
    iterations: int
    wall_time_s: float
    frames: dict = field(default_factory=dict)


def prestress_on_net(model: HemisphereModel, rtol: float = 1e-10) -> PrestressResult:
    """Relax the rods placed on the net (cheaper route) by one static Newton solve."""
    if model.configuration != "sphere":
        raise ModelError("prestress_on_net needs a model built with configuration='sphere'")
    t0 = time.perf_counter()
    system = build_rod_system(model.network)
    res = solve_static(system, rtol=rtol, max_iter=200)
    if res.success:
        system.accept(res.q)
    return PrestressResult(res.q, system, res.success, res.message, 1, res.iterations, time.perf_counter() - t0,
                           model.network.frames.state())


def prestress_by_paths(model: HemisphereModel, n_steps: int = 40, rtol: float = 1e-10) -> PrestressResult:
    """The paper's route: rod ends moved along their paths from the footprint to the equator.

    The flat grid (with its small bump) is compressed by the moving ends and
    buckles upwards; the path is taken in ``n_steps`` (adaptive) load steps,
    every converged state accepted so that the rod frames follow, and the
    last state is the relaxed hemisphere.
    """
    if model.configuration != "plane" or not model.paths:
        raise ModelError("prestress_by_paths needs a model built with configuration='plane'")
    t0 = time.perf_counter()
    system = build_rod_system(model.network)
    res = solve_incremental(system, n_steps=n_steps, paths=model.paths, t_end=1.0, rtol=rtol, max_iter=60)
    return PrestressResult(
        res.q, system, res.success, res.message, res.n_steps, int(sum(res.iterations)), time.perf_counter() - t0,
        model.network.frames.state(),
    )


def compare_shapes(model: HemisphereModel, qa: np.ndarray, qb: np.ndarray) -> dict[str, float]:
    """How far two states of the same model are apart, and from the sphere (relative to R)."""
    R = model.radius
    xa, xb = model.positions(qa), model.positions(qb)
    d = np.linalg.norm(xa - xb, axis=1)

    def off_sphere(x):
        return float(np.max(np.abs(np.linalg.norm(x, axis=1) - R)))

    return {
        "max_node_distance_over_R": float(d.max() / R),
        "rms_node_distance_over_R": float(np.sqrt(np.mean(d**2)) / R),
        "apex_height_a_over_R": float(xa[model.apex_nodes, 2].mean() / R),
        "apex_height_b_over_R": float(xb[model.apex_nodes, 2].mean() / R),
        "max_off_sphere_a_over_R": off_sphere(xa) / R,
        "max_off_sphere_b_over_R": off_sphere(xb) / R,
    }
