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

This module provides the three pieces of that check:

* :func:`force_density_net` - the MRA model of the net: ropes with a rest
  length ``1e-9`` of the spacing and ``EA = q L``, so their force is
  ``q (l - L)``, a force density ``q`` to nine digits; the loads are point
  masses under gravity, so the MRA relaxation drives it;
* :func:`force_density_solve` - the same net as a linear force-density
  problem solved with pyamg;
* :func:`membrane_centre_deflection` - the continuum solution by scikit-fem
  (quadratic triangles) with the linear system solved by pyamg.
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
