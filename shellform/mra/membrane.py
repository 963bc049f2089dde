"""Continuum limit of a hanging net: the uniformly loaded membrane.

A square net of spacing ``h`` whose ropes all have the same force density
``q`` (force over length) and which carries a load ``p h^2`` at every node
satisfies, in the vertical direction,

    q sum_j (z_j - z_i) + p h^2 = 0,

the five-point Laplacian: as ``h -> 0`` it tends to the membrane equation
``N laplacian(z) = -p`` with ``N = q`` (rope force ``q h`` per spacing ``h``)
and ``z = 0`` on the rim, whose square solution has the centre deflection
``0.0736714 p a^2 / N`` (the series solution on a square,
:data:`shellform.validation.reference.MEMBRANE_SQUARE_COEFFICIENT`).

On an unstructured net the same equation needs the right force densities. A
triangulated net whose rope ``ij`` has the force density
``q_ij = N (cot a_ij + cot b_ij) / 2`` (``a_ij``, ``b_ij`` the angles opposite
the rope in its two triangles) and whose nodes carry a third of the load on
each triangle around them *is* the linear finite-element discretisation of the
membrane (the cotangent Laplacian), and converges to it at second order. Equal
force densities on triangles converge to a different surface: on a lattice of
equilateral triangles to the membrane of force ``sqrt(3) q``, on the irregular
triangles of a mesher to none of constant force.

This module provides the pieces of these checks:

* :func:`force_density_net` - the MRA model of the net: ropes with a rest
  length ``1e-9`` of the spacing and ``EA = q L``, so their force is
  ``q (l - L)``, a force density ``q`` to nine digits; the loads are point
  masses under gravity, so the MRA relaxation drives it;
* :func:`force_density_solve` - the same net as a linear force-density
  problem solved with pyamg;
* :func:`membrane_centre_deflection` - the continuum solution by scikit-fem
  (quadratic triangles) with the linear system solved by pyamg;
* :func:`membrane_force_densities`, :func:`unstructured_force_density_net` and
  :func:`deflection_at` - the same for an unstructured net of triangles or quads.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..errors import ModelError
from ..geometry.grids import QuadGrid, rectangle_grid
from ..model import Structure

REST_FRACTION = 1e-9


def force_density_net(n: int, side: float = 1.0, q: float = 1.0, p: float = 1.0, g: float = 9.81,
                      grid: QuadGrid | None = None):
    """Square net of ``n x n`` cells with equal force densities, rim fixed.

    Returns ``(structure, grid, centre_node)``; the load ``p h^2`` of every
    interior node is the weight of a point mass ``p h^2 / g``.
    """
    if n < 2 or n % 2:
        raise ModelError(f"force-density net: n must be even and at least 2 (a node at the centre), got {n}")
    grid = rectangle_grid(side, side, n, n) if grid is None else grid
    h = side / n
    s = Structure(grid.nodes)
    L = REST_FRACTION * h
    s.add_ropes(grid.edges, EA=q * L, rest_length=L, name="ropes")
    interior = np.setdiff1d(np.arange(grid.n_nodes), grid.boundary)
    s.add_point_mass(interior, p * h * h / g)
    s.set_gravity((0.0, 0.0, -g))
    s.fix(grid.boundary)
    centre = int(grid.nodes_at([[n // 2, n // 2]])[0])
    return s, grid, centre


def force_density_solve(n: int, side: float = 1.0, q: float = 1.0, p: float = 1.0, tol: float = 1e-12) -> np.ndarray:
    """Deflections (positive down) of the equal-force-density net, by pyamg.

    Solves ``q (4 z_i - sum_j z_j) = p h^2`` on the ``(n - 1)^2`` interior
    nodes; returns them as an ``(n - 1, n - 1)`` array.
    """
    import pyamg

    m = n - 1
    h = side / n
    T = sp.diags([-np.ones(m - 1), 2 * np.ones(m), -np.ones(m - 1)], [-1, 0, 1])
    A = (sp.kron(T, sp.eye(m)) + sp.kron(sp.eye(m), T)).tocsr() * q
    b = np.full(m * m, p * h * h)
    ml = pyamg.ruge_stuben_solver(A)
    z = ml.solve(b, tol=tol, accel="cg", maxiter=200)
    return z.reshape(m, m)


def membrane_centre_deflection(side: float = 1.0, N: float = 1.0, p: float = 1.0, refine: int = 6,
                               tol: float = 1e-12) -> float:
    """Centre deflection of the square membrane ``N laplacian(w) = -p``, ``w = 0`` on the rim.

    scikit-fem with quadratic triangles on a ``2^refine`` subdivided square;
    the linear system goes to CG preconditioned by pyamg's smoothed aggregation.
    """
    import pyamg
    import skfem
    from skfem.helpers import dot, grad

    mesh = skfem.MeshTri.init_symmetric().scaled((side, side)).refined(refine)
    basis = skfem.Basis(mesh, skfem.ElementTriP2())

    @skfem.BilinearForm
    def stiffness(u, v, _):
        return N * dot(grad(u), grad(v))

    @skfem.LinearForm
    def load(v, _):
        return p * v

    K = stiffness.assemble(basis)
    f = load.assemble(basis)
    D = basis.get_dofs().all()
    I = basis.complement_dofs(D)
    A = K[I][:, I].tocsr()
    ml = pyamg.smoothed_aggregation_solver(A, symmetry="symmetric")
    w = np.zeros(basis.N)
    w[I] = ml.solve(f[I], tol=tol, accel="cg", maxiter=500)
    centre = basis.probes(np.array([[0.5 * side], [0.5 * side]]))
    return float((centre @ w)[0])


def membrane_force_densities(nodes: np.ndarray, triangles: np.ndarray, N: float = 1.0):
    """Force densities of a triangulated net that make it the membrane of force ``N``, and its nodes' areas.

    Returns
    -------
    edges : ndarray (m, 2)
        Every edge of the triangles once (lower node first).
    q : ndarray (m,)
        ``N (cot a + cot b) / 2`` from the angles opposite the edge (one term on the rim).
    area : ndarray (n,)
        A third of the area of every triangle at a node (the node's share of a uniform load).
    """
    x = np.asarray(nodes, dtype=float)
    t = np.asarray(triangles, dtype=np.int64)
    e, cot = [], []
    for k in range(3):
        a, b, o = t[:, k], t[:, (k + 1) % 3], t[:, (k + 2) % 3]
        u, v = x[a] - x[o], x[b] - x[o]
        e.append(np.sort(np.column_stack([a, b]), axis=1))
        cot.append(np.einsum("ij,ij->i", u, v) / np.linalg.norm(np.cross(u, v), axis=1))
    edges, inverse = np.unique(np.concatenate(e), axis=0, return_inverse=True)
    q = 0.5 * N * np.bincount(inverse.ravel(), weights=np.concatenate(cot), minlength=len(edges))
    p = x[t]
    tri_area = 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1)
    area = np.bincount(t.ravel(), weights=np.repeat(tri_area / 3.0, 3), minlength=len(x))
    return edges, q, area


def unstructured_force_density_net(nodes: np.ndarray, edges: np.ndarray, q: np.ndarray, area: np.ndarray,
                                   boundary: np.ndarray, p: float = 1.0, g: float = 9.81) -> Structure:
    """The MRA model of a net with the force density ``q`` of every edge and the load ``p area`` at every node.

    Ropes of rest length ``1e-9`` of their own length and ``EA = q L`` (as
    :func:`force_density_net`), the loads as weights of point masses, the
    ``boundary`` fixed. Edges of zero force density carry nothing and are left out.
    """
    x = np.asarray(nodes, dtype=float)
    q = np.asarray(q, dtype=float)
    if np.any(q < 0):
        k = int(np.argmin(q))
        raise ModelError(f"force-density net: edge {k} (nodes {edges[k].tolist()}) has the negative force density "
                         f"{q[k]:.3g}: a rope cannot push (two obtuse angles face it)")
    keep = q > 0
    L = REST_FRACTION * np.linalg.norm(x[edges[keep, 1]] - x[edges[keep, 0]], axis=1)
    s = Structure(x)
    s.add_ropes(edges[keep], EA=q[keep] * L, rest_length=L, name="ropes")
    interior = np.setdiff1d(np.arange(len(x)), boundary)
    s.add_point_mass(interior, p * np.asarray(area, dtype=float)[interior] / g)
    s.set_gravity((0.0, 0.0, -g))
    s.fix(boundary)
    return s


def deflection_at(nodes: np.ndarray, faces: np.ndarray, w: np.ndarray, point) -> float:
    """The piecewise-linear interpolation of the node values ``w`` at ``point`` (x, y) over triangles or quads."""
    x = np.asarray(nodes, dtype=float)[:, :2]
    f = np.asarray(faces, dtype=np.int64)
    tris = f if f.shape[1] == 3 else np.concatenate([f[:, [0, 1, 2]], f[:, [0, 2, 3]]])
    a, b, c = x[tris[:, 0]], x[tris[:, 1]], x[tris[:, 2]]
    d = np.asarray(point, dtype=float)[:2] - a
    e1, e2 = b - a, c - a
    det = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    l1 = (d[:, 0] * e2[:, 1] - d[:, 1] * e2[:, 0]) / det
    l2 = (e1[:, 0] * d[:, 1] - e1[:, 1] * d[:, 0]) / det
    inside = np.flatnonzero((l1 >= -1e-12) & (l2 >= -1e-12) & (l1 + l2 <= 1 + 1e-12))
    if not inside.size:
        raise ModelError(f"deflection_at: the point {list(point)} lies on no face of the net")
    k = inside[0]
    return float((1 - l1[k] - l2[k]) * w[tris[k, 0]] + l1[k] * w[tris[k, 1]] + l2[k] * w[tris[k, 2]])
