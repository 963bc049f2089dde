"""Start states for form finding: flat, or on a B-spline surface close to the final shape.

The MRA paper starts large nets from a NURBS surface built in a preliminary
phase, near the hanging shape, instead of from the flat planform, and reports
that the relaxation then costs much less. :func:`surface_start` places the
free nodes of a net on a height-field B-spline (planform ``x, y`` kept,
``z`` from the surface); :func:`fit_height_field` builds such a surface by
least squares from scattered points (for example a coarse hanging net).
"""

from __future__ import annotations

import numpy as np

from ..errors import ModelError
from ..geometry.bspline import HeightField, basis_functions, height_field
from .net import HangingNet


def surface_start(net: HangingNet, surface: HeightField) -> np.ndarray:
    """Start state with every free node lowered/raised onto ``surface``.

    Suspension points keep their positions; the surface is added to the
    nodes' planform height, so a surface that is zero on the rim leaves
    lifted frames where they are.
    """
    s = net.structure
    x = s.nodes.copy()
    free = np.ones(s.n_nodes, dtype=bool)
    free[net.supports] = False
    x[free, 2] += surface.z(x[free, 0], x[free, 1])
    return x.ravel()


def fit_height_field(points, x_range, y_range, n_ctrl=(6, 6), degree: int = 3,
                     smoothing: float = 1e-6) -> HeightField:
    """Least-squares height-field B-spline through scattered points ``(x, y, z)``.

    A small second-difference penalty on the control heights (``smoothing``
    relative to the data term) keeps the fit well posed where data are sparse.
    """
    p = np.asarray(points, dtype=float)
    if p.ndim != 2 or p.shape[1] != 3 or len(p) < 4:
        raise ModelError(f"surface fit: expected at least 4 points of shape (n, 3), got {p.shape}")
    nu, nv = (int(n_ctrl), int(n_ctrl)) if np.ndim(n_ctrl) == 0 else (int(n_ctrl[0]), int(n_ctrl[1]))
    hf = height_field(np.zeros((nu, nv)), x_range, y_range, degree)
    srf = hf.surface
    (x0, x1), (y0, y1) = hf.x_range, hf.y_range
    (u0, u1), (v0, v1) = srf.domain
    u = u0 + (u1 - u0) * np.clip((p[:, 0] - x0) / (x1 - x0), 0, 1)
    v = v0 + (v1 - v0) * np.clip((p[:, 1] - y0) / (y1 - y0), 0, 1)
    Nu = basis_functions(srf.knots_u, srf.degree_u, u)
    Nv = basis_functions(srf.knots_v, srf.degree_v, v)
    A = (Nu[:, :, None] * Nv[:, None, :]).reshape(len(p), nu * nv)
    D = []
    I = np.eye(nu * nv).reshape(nu, nv, nu * nv)
    if nu >= 3:
        D.append((I[:-2] - 2 * I[1:-1] + I[2:]).reshape(-1, nu * nv))
    if nv >= 3:
        D.append((I[:, :-2] - 2 * I[:, 1:-1] + I[:, 2:]).reshape(-1, nu * nv))
    lhs = A.T @ A
    if D:
        D = np.concatenate(D)
        lhs = lhs + smoothing * np.trace(lhs) / len(lhs) * (D.T @ D)
    z = np.linalg.solve(lhs, A.T @ p[:, 2])
    srf.control_points[..., 2] = z.reshape(nu, nv)
    return hf
