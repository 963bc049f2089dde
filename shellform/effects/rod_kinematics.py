"""Kinematics of discrete elastic rods on the flat DOF vector.

A discrete rod is a polyline of nodes ``x_0 .. x_{N-1}`` with one twist angle
``theta^j`` per edge ``e^j = x_{j+1} - x_j``. Every edge carries

* a *reference frame* ``(t^j, u^j, v^j)``: the unit tangent ``t^j = e^j / |e^j|``
  and a director ``u^j`` perpendicular to it (``v^j = t^j x u^j``), and
* a *material frame* ``(t^j, m1^j, m2^j)``: the reference frame rotated about
  the tangent by ``theta^j``.

Reference frames are carried between configurations by *time-parallel
transport*: when the tangent of an edge moves from ``s`` (its value in the last
accepted configuration) to ``t``, the director is rotated by the smallest
rotation taking ``s`` to ``t``. Nothing in the reference frame spins about the
tangent, so all the twist of the rod lives in ``theta`` and in the *reference
twist* ``m_i``: the angle about ``t^i`` from the space-parallel transport of
``u^{i-1}`` (from ``t^{i-1}`` to ``t^i``) to ``u^i``.

How the reference state is held
-------------------------------
Effects are evaluated at arbitrary trial states ``q`` (Newton iterates,
line-search points, finite differences). The :class:`ReferenceFrames` object
stores, for the last *accepted* configuration, the tangents ``s^j``, the
directors ``u^j`` and the reference twist ``m_i``. At a trial state the
energies are functions of ``q`` alone, with the directors transported from that
stored state. The reference twist at ``q`` then follows in closed form from
the holonomy of parallel transport around the geodesic quadrilateral
``s^{i-1} -> t^{i-1} -> t^i -> s^i``:

    m_i(q) = m_i(stored) - Omega(s^{i-1}, t^{i-1}, t^i) - Omega(s^{i-1}, t^i, s^i),

with ``Omega(a, b, c) = 2 atan2(a . (b x c), 1 + a.b + b.c + c.a)`` the signed
solid angle of a spherical triangle. This expression is smooth in ``q``, keeps
``m`` continuous (no 2 pi jumps), and its exact derivatives are simple; that is
what makes the analytic Hessians of the bending and twisting energies exact at
every trial state, not only at the stored one.

:meth:`ReferenceFrames.update` moves the stored state to an accepted ``q``. It
does not change any energy at that ``q``; it changes the *chart* (which motions
of the material frame count as "theta held fixed"), so the forces on nodes
whose edges carry a twist moment change by terms proportional to that moment.
At an equilibrium with free twist angles those moments vanish and the update
leaves the equilibrium unchanged. Solvers call it after every converged load or
time step (the discrete counterpart of time-parallel transport along the path);
within one Newton solve the stored state stays put, so Newton sees one smooth
energy and converges quadratically.
"""

from __future__ import annotations

import numpy as np

from ..geometry.vectors import cross

# -- elementary vector operations (rows are vectors) ---------------------------------


def dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise dot product of two ``(n, 3)`` arrays."""
    return np.einsum("ij,ij->i", a, b)


def normalize(a: np.ndarray) -> np.ndarray:
    """Rows of ``a`` scaled to unit length."""
    return a / np.linalg.norm(a, axis=-1, keepdims=True)


def skew(a: np.ndarray) -> np.ndarray:
    """Cross-product matrices: ``skew(a)[k] @ b == cross(a[k], b)``; shape (n, 3, 3)."""
    S = np.zeros(a.shape[:-1] + (3, 3))
    S[..., 0, 1] = -a[..., 2]
    S[..., 0, 2] = a[..., 1]
    S[..., 1, 0] = a[..., 2]
    S[..., 1, 2] = -a[..., 0]
    S[..., 2, 0] = -a[..., 1]
    S[..., 2, 1] = a[..., 0]
    return S


def parallel_transport(v: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Rotate ``v`` by the smallest rotation that takes unit vector ``a`` to unit vector ``b``.

    ``P v = (a.b) v + (a x b) x v + ((a x b).v) (a x b) / (1 + a.b)``; the
    rotation is undefined for ``b = -a`` only.
    """
    c = cross(a, b)
    cos = dot(a, b)
    return cos[:, None] * v + cross(c, v) + (dot(c, v) / (1.0 + cos))[:, None] * c


def signed_angle(u: np.ndarray, v: np.ndarray, axis: np.ndarray) -> np.ndarray:
    """Angle in (-pi, pi] that rotates ``u`` onto ``v`` about the unit ``axis`` (right hand)."""
    return np.arctan2(dot(cross(u, v), axis), dot(u, v))


def curvature_binormal(t0: np.ndarray, t1: np.ndarray) -> np.ndarray:
    """Discrete (integrated) curvature binormal ``2 t0 x t1 / (1 + t0 . t1)``.

    Its length is ``2 tan(phi / 2)`` with ``phi`` the turning angle between
    the edges; divided by the Voronoi length it approximates the curvature.
    """
    return 2.0 * cross(t0, t1) / (1.0 + dot(t0, t1))[:, None]


def solid_angle(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Signed area of the spherical triangle ``a, b, c`` (unit vectors), in (-2 pi, 2 pi)."""
    return 2.0 * np.arctan2(dot(a, cross(b, c)), 1.0 + dot(a, b) + dot(b, c) + dot(c, a))


def perpendicular_director(t: np.ndarray) -> np.ndarray:
    """A unit vector perpendicular to each unit ``t``.

    Prefers the direction of ``z`` projected off ``t`` (for rods lying in a
    horizontal plane the first director is then vertical) and falls back to
    ``x`` where ``t`` is nearly vertical.
    """
    pick = np.where(np.abs(t[:, 2:3]) < 0.9, np.array([[0.0, 0.0, 1.0]]), np.array([[1.0, 0.0, 0.0]]))
    return normalize(pick - dot(pick, t)[:, None] * t)


# -- quantities of a configuration ----------------------------------------------------


def node_positions(q: np.ndarray, n_nodes: int) -> np.ndarray:
    """Node coordinates ``(n_nodes, 3)`` from the flat DOF vector."""
    return q[: 3 * n_nodes].reshape(n_nodes, 3)


def edge_vectors(x: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """Edge vectors ``x[b] - x[a]`` of edges ``(m, 2)``."""
    return x[edges[:, 1]] - x[edges[:, 0]]


def voronoi_lengths(edge_length: np.ndarray, hinge_edges: np.ndarray) -> np.ndarray:
    """Voronoi length of each interior node: half the sum of its two edges' lengths."""
    return 0.5 * (edge_length[hinge_edges[:, 0]] + edge_length[hinge_edges[:, 1]])


def material_frames(u: np.ndarray, t: np.ndarray, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Material directors ``m1 = cos(theta) u + sin(theta) v``, ``m2 = -sin(theta) u + cos(theta) v``."""
    v = cross(t, u)
    c, s = np.cos(theta)[:, None], np.sin(theta)[:, None]
    return c * u + s * v, -s * u + c * v


def material_curvatures(kb: np.ndarray, m1: np.ndarray, m2: np.ndarray) -> np.ndarray:
    """Components ``(kb . m2, -kb . m1)`` of the curvature binormal in a material frame, shape (n, 2)."""
    return np.stack([dot(kb, m2), -dot(kb, m1)], axis=1)


def space_parallel_directors(tangents: np.ndarray, first: np.ndarray, chains: np.ndarray) -> np.ndarray:
    """Directors carried along chains of edges by space-parallel transport.

    Parameters
    ----------
    tangents : ndarray (m, 3)
        Unit tangents of all edges.
    first : ndarray (m, 3)
        Director to use on the first edge of every chain (only those rows are read).
    chains : ndarray (m,)
        For every edge, the index of the preceding edge along its rod, or -1
        for the first edge of a rod. Edges must be listed after their
        predecessor.

    Returns
    -------
    ndarray (m, 3)
        Unit directors perpendicular to the tangents.

    Notes
    -----
    Used once when a network is built. The transport is sequential along a
    rod, so the loop runs over the position along the rods (all rods at once),
    not over edges.
    """
    m = len(tangents)
    u = np.zeros((m, 3))
    depth = np.zeros(m, dtype=np.int64)
    # depth of each edge along its chain (predecessors come first)
    for j in np.flatnonzero(chains >= 0):
        depth[j] = depth[chains[j]] + 1
    start = chains < 0
    u[start] = normalize(first[start] - dot(first[start], tangents[start])[:, None] * tangents[start])
    for d in range(1, int(depth.max(initial=0)) + 1):
        k = np.flatnonzero(depth == d)
        p = chains[k]
        u[k] = parallel_transport(u[p], tangents[p], tangents[k])
    # remove round-off drift from the perpendicularity
    return normalize(u - dot(u, tangents)[:, None] * tangents)


class ReferenceFrames:
    """Reference frames and reference twist of all rod edges at the last accepted state.

    Parameters
    ----------
    n_nodes : int
        Number of nodes of the structure (the translations come first in ``q``).
    edges : ndarray (m, 2)
        Node indices of every rod edge (oriented along its rod).
    hinges : ndarray (h, 2)
        The two edges (into ``edges``) meeting at every interior node.
    q : ndarray
        Configuration that defines the initial state.
    directors : ndarray (m, 3)
        Initial unit directors, perpendicular to the edges of ``q``.

    Attributes
    ----------
    tangent : ndarray (m, 3)
        Stored unit tangents ``s``.
    director : ndarray (m, 3)
        Stored reference directors ``u`` (perpendicular to ``s``).
    twist : ndarray (h,)
        Stored reference twist ``m`` at every hinge.
    accepted : int
        How many states have been accepted since construction.
    anchored : ndarray (m,) of bool
        Edges whose frames stay where they were anchored (:meth:`anchor`).
    """

    def __init__(self, n_nodes: int, edges: np.ndarray, hinges: np.ndarray, q: np.ndarray, directors: np.ndarray):
        self.n_nodes = int(n_nodes)
        self.edges = np.asarray(edges, dtype=np.int64)
        self.hinges = np.asarray(hinges, dtype=np.int64)
        x = node_positions(np.asarray(q, dtype=float), self.n_nodes)
        self.tangent = normalize(edge_vectors(x, self.edges))
        self.director = normalize(directors - dot(directors, self.tangent)[:, None] * self.tangent)
        h0, h1 = self.hinges[:, 0], self.hinges[:, 1]
        moved = parallel_transport(self.director[h0], self.tangent[h0], self.tangent[h1])
        self.twist = signed_angle(moved, self.director[h1], self.tangent[h1])
        self._positions = x.copy()
        self.accepted = 0
        self._hinge_cache = None
        self.anchored = np.zeros(len(self.edges), dtype=bool)

    # -- evaluation at a trial state ------------------------------------------------
    def tangents(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Unit tangents and lengths of all edges at ``q``."""
        e = edge_vectors(node_positions(q, self.n_nodes), self.edges)
        length = np.linalg.norm(e, axis=1)
        return e / length[:, None], length

    def hinge_tangents(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Unit tangents (3, h) and lengths (h,) of the two edges of every hinge at ``q``, component-major.

        The bending and twisting effects both need them at the same state: the
        last result is kept with a copy of the node positions it was computed
        from and returned again while the positions are equal (a comparison
        costs a small part of the computation). The stored state plays no part.
        """
        x = node_positions(q, self.n_nodes)
        cache = self._hinge_cache
        if cache is not None and cache[0].shape == x.shape and np.array_equal(cache[0], x):
            return cache[1]
        e = edge_vectors(x, self.edges)
        length = np.linalg.norm(e, axis=1)
        t = np.ascontiguousarray((e / length[:, None]).T)
        h0, h1 = self.hinges[:, 0], self.hinges[:, 1]
        result = (np.take(t, h0, axis=1), np.take(t, h1, axis=1), length[h0], length[h1])
        for a in result:
            a.flags.writeable = False
        self._hinge_cache = (x.copy(), result)
        return result

    def directors(self, q: np.ndarray) -> np.ndarray:
        """Reference directors at ``q``: stored directors time-parallel transported to the new tangents."""
        t, _ = self.tangents(q)
        return parallel_transport(self.director, self.tangent, t)

    def reference_twist(self, q: np.ndarray) -> np.ndarray:
        """Reference twist at every hinge at ``q`` (continuous from the stored value)."""
        t, _ = self.tangents(q)
        h0, h1 = self.hinges[:, 0], self.hinges[:, 1]
        s0, s1 = self.tangent[h0], self.tangent[h1]
        return self.twist - solid_angle(s0, t[h0], t[h1]) - solid_angle(s0, t[h1], s1)

    # -- history ------------------------------------------------------------------------
    def anchor(self, edges: np.ndarray) -> None:
        """Keep the frames of ``edges`` (a bool mask or indices) at their stored state when states are accepted.

        A twist angle held fixed is measured from its edge's reference frame.
        Carried along the path by time-parallel transport, that frame depends on
        the sequence of accepted states (the holonomy of the transport), and so
        would the held twist's meaning and the equilibrium that follows from it.
        An anchored frame is transported in one piece from where it was
        anchored to the edge's current tangent, a function of that tangent
        alone. An edge that turns by 90 degrees or more from its anchor is
        anchored afresh at the state then accepted, away from the antipode
        where the transport is undefined.
        """
        mask = np.zeros(len(self.edges), dtype=bool)
        mask[np.asarray(edges)] = True
        self.anchored = mask

    def update(self, q: np.ndarray) -> bool:
        """Make ``q`` the stored state (anchored frames stay). Returns False (and does nothing) if it already is."""
        x = node_positions(np.asarray(q, dtype=float), self.n_nodes)
        if np.array_equal(x, self._positions):
            return False
        t, _ = self.tangents(q)
        keep = self.anchored & (dot(t, self.tangent) > 0.0)
        new_t = np.where(keep[:, None], self.tangent, t)
        # the reference twist at the stored tangents to be: the edges that move take their current tangents
        h0, h1 = self.hinges[:, 0], self.hinges[:, 1]
        s0, s1 = self.tangent[h0], self.tangent[h1]
        self.twist = self.twist - solid_angle(s0, new_t[h0], new_t[h1]) - solid_angle(s0, new_t[h1], s1)
        u = parallel_transport(self.director, self.tangent, t)
        self.director = np.where(keep[:, None], self.director, normalize(u - dot(u, t)[:, None] * t))
        self.tangent = new_t
        self._positions = x.copy()
        self.accepted += 1
        return True

    def state(self) -> dict[str, np.ndarray]:
        """A copy of the stored state (for rolling back a rejected step)."""
        return {
            "tangent": self.tangent.copy(),
            "director": self.director.copy(),
            "twist": self.twist.copy(),
            "positions": self._positions.copy(),
        }

    def restore(self, state: dict[str, np.ndarray]) -> None:
        """Return to a state saved by :meth:`state`."""
        self.tangent = state["tangent"].copy()
        self.director = state["director"].copy()
        self.twist = state["twist"].copy()
        self._positions = state["positions"].copy()
