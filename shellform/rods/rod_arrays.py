"""The arrays of one rod before it joins a network: per edge and per hinge, in the rod's own numbering.

A rod of ``N`` nodes has ``N - 1`` edges and ``N - 2`` hinges (interior
nodes), or ``N`` of each when closed. :func:`rod_arrays` checks the nodes and
the section against these counts and computes the rest state: edge lengths,
rest frames (space-parallel transport from the first director), Voronoi
lengths, natural curvature and integrated natural twist.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ModelError
from ..model import broadcast_property
from ..effects.rod_kinematics import (
    curvature_binormal,
    material_curvatures,
    material_frames,
    parallel_transport,
    perpendicular_director,
    signed_angle,
    space_parallel_directors,
)
from .section import RestShape, RodSection
from ..geometry.sections import SectionShape


@dataclass(frozen=True)
class RodArrays:
    """One rod's edges and hinges with their rest state and section.

    Attributes
    ----------
    nodes : ndarray (N,)
        Structure node indices along the rod.
    edge_nodes : ndarray (m, 2)
        End nodes of each edge, oriented along the rod.
    rest_length, EA : ndarray (m,)
    mass_per_length, rotational_inertia : float
        Per unit length, the same along the rod.
    director : ndarray (m, 3)
        First director of each edge's rest frame.
    hinge_edges : ndarray (h, 2)
        The edges (before, after) at each hinge, numbered along the rod.
    voronoi, EI, EI2, GJ : ndarray (h,)
        ``EI`` and ``EI2`` the stiffness of the material curvatures
        ``omega_1`` and ``omega_2``.
    shape : SectionShape or None
        The section's geometry, for stresses.
    natural_curvature : ndarray (h, 2, 2)
        Integrated, in the frame of the edge before ``[:, 0]`` and after ``[:, 1]``.
    natural_twist : ndarray (h,)
        Integrated (radians): the natural twist rate times the Voronoi length,
        plus, unless the rod is straight when unstressed, the reference twist
        of the rest frames (then the rest frames carry no twist stress).
    """

    nodes: np.ndarray
    edge_nodes: np.ndarray
    rest_length: np.ndarray
    EA: np.ndarray
    mass_per_length: float
    rotational_inertia: float
    director: np.ndarray
    hinge_edges: np.ndarray
    voronoi: np.ndarray
    EI: np.ndarray
    EI2: np.ndarray
    GJ: np.ndarray
    natural_curvature: np.ndarray
    natural_twist: np.ndarray
    shape: SectionShape | None = None

    @property
    def hinge_nodes(self) -> np.ndarray:
        """The three nodes ``(x0, x1, x2)`` of each hinge, shape (h, 3)."""
        e0, e1 = self.hinge_edges[:, 0], self.hinge_edges[:, 1]
        if not len(e0):
            return np.zeros((0, 3), int)
        return np.stack([self.edge_nodes[e0, 0], self.edge_nodes[e0, 1], self.edge_nodes[e1, 1]], axis=1)


def rod_arrays(x: np.ndarray, nodes, section: RodSection, rest: RestShape, closed: bool, name: str) -> RodArrays:
    """Check a rod through the nodes ``nodes`` of the coordinates ``x`` and compute its arrays.

    Errors are :class:`ModelError` naming the rod ``name``.
    """
    idx = _checked_nodes(nodes, len(x), closed, name)
    e_nodes = _consecutive_pairs(idx, closed)
    vec, length = _edge_vectors(x, e_nodes, name)
    m = len(e_nodes)
    rest_length = length if rest.rest_length is None else broadcast_property(
        rest.rest_length, m, f"rod {name!r} rest_length", item="edge")
    EA = broadcast_property(section.EA, m, f"rod {name!r} EA", item="edge")
    mpl = broadcast_property(section.mass_per_length, 1, f"rod {name!r} mass_per_length", True, "entry")[0]
    rot = broadcast_property(section.rotational_inertia, 1, f"rod {name!r} rotational_inertia", True, "entry")[0]

    hinge = _consecutive_pairs(np.arange(m), closed)
    h = len(hinge)
    EI = broadcast_property(section.EI, h, f"rod {name!r} EI", item="hinge") if h else np.zeros(0)
    EI2 = EI if section.EI2 is None else (
        broadcast_property(section.EI2, h, f"rod {name!r} EI2", item="hinge") if h else np.zeros(0))
    GJ = broadcast_property(section.GJ, h, f"rod {name!r} GJ", item="hinge") if h else np.zeros(0)
    twist_rate = _twist_rates(rest.natural_twist, h, name)

    t = vec / length[:, None]
    u = _rest_directors(t, rest.director, name)
    e0, e1 = hinge[:, 0], hinge[:, 1]
    voronoi = 0.5 * (rest_length[e0] + rest_length[e1])
    omega = _natural_curvature(rest.natural_curvature, t, u, hinge, voronoi, name)
    # a rod straight when unstressed is untwisted then: the twist of its rest frames is a deformation
    straight = isinstance(rest.natural_curvature, str) and rest.natural_curvature == "straight"
    tau_bar = twist_rate * voronoi + (0.0 if straight else _reference_twist(t, u, hinge))
    return RodArrays(
        nodes=idx, edge_nodes=e_nodes, rest_length=rest_length, EA=EA, mass_per_length=mpl,
        rotational_inertia=rot, director=u, hinge_edges=hinge, voronoi=voronoi, EI=EI, EI2=EI2, GJ=GJ,
        natural_curvature=omega, natural_twist=tau_bar, shape=section.shape,
    )


def _checked_nodes(nodes, n_nodes: int, closed: bool, name: str) -> np.ndarray:
    """The node indices of a rod as int64, each a node of the structure and none twice."""
    idx = np.asarray(nodes)
    if idx.ndim != 1 or len(idx) < (3 if closed else 2):
        raise ModelError(f"rod {name!r}: expected a 1-D list of at least {3 if closed else 2} node indices")
    if not np.issubdtype(idx.dtype, np.integer):
        raise ModelError(f"rod {name!r}: node indices must be integers, got {idx.dtype}")
    idx = idx.astype(np.int64)
    if idx.min() < 0 or idx.max() >= n_nodes:
        bad = idx[(idx < 0) | (idx >= n_nodes)][0]
        raise ModelError(f"rod {name!r}: node index {bad} is out of range (the structure has {n_nodes} nodes)")
    if len(np.unique(idx)) != len(idx):
        raise ModelError(f"rod {name!r}: a node appears twice along the rod")
    return idx


def _consecutive_pairs(items: np.ndarray, closed: bool) -> np.ndarray:
    """Neighbours along a chain, shape (k, 2): nodes of the edges, or edges of the hinges."""
    if closed:
        return np.stack([items, np.roll(items, -1)], axis=1)
    return np.stack([items[:-1], items[1:]], axis=1)


def _edge_vectors(x: np.ndarray, e_nodes: np.ndarray, name: str) -> tuple[np.ndarray, np.ndarray]:
    """Edge vectors and lengths; an edge of zero length (relative to the structure's size) is refused."""
    vec = x[e_nodes[:, 1]] - x[e_nodes[:, 0]]
    length = np.linalg.norm(vec, axis=1)
    scale = max(float(np.ptp(x, axis=0).max()), 1e-300)
    short = np.flatnonzero(length <= 1e-12 * scale)
    if short.size:
        k = int(short[0])
        raise ModelError(f"rod {name!r}: edge {k} (nodes {e_nodes[k, 0]}-{e_nodes[k, 1]}) has zero length")
    return vec, length


def _twist_rates(natural_twist, h: int, name: str) -> np.ndarray:
    """The natural twist rate of each hinge [rad/m] (any finite value, signed)."""
    rate = np.asarray(natural_twist, dtype=float)
    rate = np.broadcast_to(rate, (h,)) if rate.ndim == 0 else rate
    if rate.shape != (h,) or not np.all(np.isfinite(rate)):
        raise ModelError(f"rod {name!r}: natural_twist must be finite, a scalar or {h} values")
    return rate


def _rest_directors(t: np.ndarray, director, name: str) -> np.ndarray:
    """Directors of the rest frames: given per edge, or transported along the rod from the first edge's."""
    m = len(t)
    d = None if director is None else np.asarray(director, dtype=float)
    if d is None or d.shape == (3,):
        return space_parallel_directors(t, _first_directors(t, director, name), np.arange(-1, m - 1))
    if d.shape != (m, 3) or not np.all(np.isfinite(d)):
        raise ModelError(f"rod {name!r}: director must be 3 finite numbers or one such vector per edge ({m}, 3)")
    p = d - np.einsum("ij,ij->i", d, t)[:, None] * t
    size = np.linalg.norm(p, axis=1)
    bad = np.flatnonzero(size < 1e-8 * np.maximum(np.linalg.norm(d, axis=1), 1e-300))
    if bad.size:
        raise ModelError(f"rod {name!r}: the director of edge {int(bad[0])} is zero or parallel to the edge")
    return p / size[:, None]


def _first_directors(t: np.ndarray, director, name: str) -> np.ndarray:
    """Start of the transport: the first edge's director (given or chosen), zeros elsewhere."""
    first = np.zeros((len(t), 3))
    if director is None:
        first[0] = perpendicular_director(t[:1])[0]
        return first
    d = np.asarray(director, dtype=float)
    if d.shape != (3,) or not np.all(np.isfinite(d)):
        raise ModelError(f"rod {name!r}: director must be 3 finite numbers")
    d = d - (d @ t[0]) * t[0]
    if np.linalg.norm(d) < 1e-8 * max(np.linalg.norm(np.asarray(director, float)), 1e-300):
        raise ModelError(f"rod {name!r}: director is parallel to the first edge")
    first[0] = d / np.linalg.norm(d)
    return first


def _reference_twist(t: np.ndarray, u: np.ndarray, hinge: np.ndarray) -> np.ndarray:
    """Angle at each hinge from the transported director of the edge before to the director after."""
    if not len(hinge):
        return np.zeros(0)
    e0, e1 = hinge[:, 0], hinge[:, 1]
    return signed_angle(parallel_transport(u[e0], t[e0], t[e1]), u[e1], t[e1])


def _natural_curvature(natural, t: np.ndarray, u: np.ndarray, hinge: np.ndarray, voronoi: np.ndarray,
                       name: str) -> np.ndarray:
    """Integrated natural material curvature (h, 2, 2) of ``RestShape.natural_curvature``."""
    h = len(hinge)
    omega = np.zeros((h, 2, 2))
    if isinstance(natural, str):
        if natural == "rest":
            e0, e1 = hinge[:, 0], hinge[:, 1]
            kb = curvature_binormal(t[e0], t[e1]) if h else np.zeros((0, 3))
            for j, e in enumerate((e0, e1)):
                m1, m2 = material_frames(u[e], t[e], np.zeros(h))
                omega[:, j] = material_curvatures(kb, m1, m2)
        elif natural != "straight":
            raise ModelError(f"rod {name!r}: natural_curvature must be 'rest', 'straight' or an array")
        return omega
    kappa = np.asarray(natural, dtype=float)
    if kappa.shape != (h, 2) or not np.all(np.isfinite(kappa)):
        raise ModelError(f"rod {name!r}: natural_curvature array must have shape ({h}, 2) and be finite")
    omega[:] = (kappa * voronoi[:, None])[:, None, :]
    return omega
