"""B-spline and NURBS surfaces in pure NumPy.

A tensor-product surface of degrees ``(p, q)`` with control points
``P[i, j]`` (shape ``(nu, nv, 3)``), weights ``w[i, j]`` and knot vectors
``U``, ``V`` is

    S(u, v) = sum_ij N_i,p(u) N_j,q(v) w_ij P_ij / sum_ij N_i,p(u) N_j,q(v) w_ij.

The basis functions are evaluated by the Cox-de Boor recursion, vectorised
over all parameter values at once (one pass per degree). The default knot
vectors are clamped and uniform, so the surface passes through the four
corner control points and its edges are the B-spline curves of the boundary
rows of the control net.

:func:`height_field` builds the surface ``z = f(x, y)`` over a rectangle whose
control points sit at the Greville abscissae: with that placement ``x`` and
``y`` are exactly linear in ``u`` and ``v`` (linear precision of B-splines),
so a planform point maps to its parameters by a scaling and the surface can be
sampled under any planform grid.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ModelError


def clamped_uniform_knots(n_ctrl: int, degree: int) -> np.ndarray:
    """Clamped uniform knot vector on [0, 1] for ``n_ctrl`` control points."""
    if degree < 1 or n_ctrl < degree + 1:
        raise ModelError(f"B-spline: {n_ctrl} control points cannot carry degree {degree} (need at least degree + 1)")
    inner = np.linspace(0.0, 1.0, n_ctrl - degree + 1)
    return np.concatenate([np.zeros(degree), inner, np.ones(degree)])


def greville_abscissae(knots: np.ndarray, degree: int) -> np.ndarray:
    """Averages of ``degree`` consecutive interior knots: the parameter 'position' of each control point."""
    n_ctrl = len(knots) - degree - 1
    return np.array([knots[i + 1 : i + degree + 1].mean() for i in range(n_ctrl)])


def basis_functions(knots: np.ndarray, degree: int, u) -> np.ndarray:
    """All B-spline basis functions at the parameters ``u``.

    Returns
    -------
    N : ndarray, shape (len(u), n_ctrl)
        ``N[k, i] = N_i,degree(u_k)``; rows sum to one inside the knot range.
    """
    knots = np.asarray(knots, dtype=float)
    u = np.atleast_1d(np.asarray(u, dtype=float))
    n_ctrl = len(knots) - degree - 1
    lo, hi = knots[degree], knots[-degree - 1]
    if np.any(u < lo - 1e-12) or np.any(u > hi + 1e-12):
        raise ModelError(f"B-spline: parameters must lie in [{lo}, {hi}], got range [{u.min()}, {u.max()}]")
    u = np.clip(u, lo, hi)
    # degree 0: indicator of the knot span; the last span is closed so u = hi counts
    n_spans = len(knots) - 1
    left, right = knots[:-1], knots[1:]
    N = ((u[:, None] >= left[None, :]) & (u[:, None] < right[None, :])).astype(float)
    last = np.flatnonzero(right > left)[-1]
    N[u >= hi, :] = 0.0
    N[u >= hi, last] = 1.0
    for p in range(1, degree + 1):
        m = n_spans - p
        d1 = knots[p : p + m] - knots[:m]
        d2 = knots[p + 1 : p + 1 + m] - knots[1 : 1 + m]
        with np.errstate(divide="ignore", invalid="ignore"):
            a = np.where(d1 > 0, (u[:, None] - knots[:m]) / d1, 0.0)
            b = np.where(d2 > 0, (knots[p + 1 : p + 1 + m] - u[:, None]) / d2, 0.0)
        N = a * N[:, :m] + b * N[:, 1 : m + 1]
    return N[:, :n_ctrl]


@dataclass
class BSplineSurface:
    """A tensor-product NURBS surface.

    Parameters
    ----------
    control_points : array_like, shape (nu, nv, 3)
        Control net, ``u`` along the first axis.
    degree_u, degree_v : int
    knots_u, knots_v : array_like, optional
        Knot vectors (default clamped uniform on [0, 1]).
    weights : array_like, shape (nu, nv), optional
        Rational weights (default all ones: a plain B-spline).
    """

    control_points: np.ndarray
    degree_u: int = 3
    degree_v: int = 3
    knots_u: np.ndarray | None = None
    knots_v: np.ndarray | None = None
    weights: np.ndarray | None = None

    def __post_init__(self):
        P = np.asarray(self.control_points, dtype=float)
        if P.ndim != 3 or P.shape[2] != 3 or min(P.shape[:2]) < 2:
            raise ModelError(f"B-spline surface: control points must have shape (nu, nv, 3), got {P.shape}")
        if not np.all(np.isfinite(P)):
            raise ModelError("B-spline surface: control points must be finite")
        self.control_points = P
        nu, nv = P.shape[:2]
        self.degree_u = int(min(self.degree_u, nu - 1))
        self.degree_v = int(min(self.degree_v, nv - 1))
        self.knots_u = self._knots(self.knots_u, nu, self.degree_u, "u")
        self.knots_v = self._knots(self.knots_v, nv, self.degree_v, "v")
        w = np.ones((nu, nv)) if self.weights is None else np.asarray(self.weights, dtype=float)
        if w.shape != (nu, nv) or not np.all(np.isfinite(w)) or np.any(w <= 0):
            raise ModelError(f"B-spline surface: weights must be positive with shape {(nu, nv)}")
        self.weights = w

    @staticmethod
    def _knots(knots, n, degree, name):
        if knots is None:
            return clamped_uniform_knots(n, degree)
        k = np.asarray(knots, dtype=float)
        if k.ndim != 1 or len(k) != n + degree + 1 or np.any(np.diff(k) < 0):
            raise ModelError(
                f"B-spline surface: knot vector {name} must be non-decreasing with {n + degree + 1} entries, "
                f"got {k.shape}"
            )
        return k

    @property
    def domain(self) -> tuple[tuple[float, float], tuple[float, float]]:
        pu, pv = self.degree_u, self.degree_v
        return (self.knots_u[pu], self.knots_u[-pu - 1]), (self.knots_v[pv], self.knots_v[-pv - 1])

    def evaluate(self, u, v) -> np.ndarray:
        """Points ``S(u_k, v_k)`` for paired parameter arrays; shape ``(len(u), 3)``."""
        u = np.atleast_1d(np.asarray(u, dtype=float))
        v = np.atleast_1d(np.asarray(v, dtype=float))
        if u.shape != v.shape:
            raise ModelError(f"B-spline surface: u and v must have the same shape, got {u.shape} and {v.shape}")
        Nu = basis_functions(self.knots_u, self.degree_u, u.ravel())
        Nv = basis_functions(self.knots_v, self.degree_v, v.ravel())
        w = self.weights
        Pw = self.control_points * w[..., None]
        num = np.einsum("ki,kj,ijc->kc", Nu, Nv, Pw)
        den = np.einsum("ki,kj,ij->k", Nu, Nv, w)
        return (num / den[:, None]).reshape(*u.shape, 3)

    def grid(self, n_u: int, n_v: int) -> np.ndarray:
        """Points on a uniform parameter grid; shape ``(n_u, n_v, 3)``."""
        (u0, u1), (v0, v1) = self.domain
        U, V = np.meshgrid(np.linspace(u0, u1, n_u), np.linspace(v0, v1, n_v), indexing="ij")
        return self.evaluate(U, V)


@dataclass
class HeightField:
    """A B-spline surface ``z(x, y)`` over the rectangle ``[x0, x1] x [y0, y1]``."""

    surface: BSplineSurface
    x_range: tuple[float, float]
    y_range: tuple[float, float]

    def z(self, x, y) -> np.ndarray:
        """Height at planform points (clipped to the rectangle)."""
        (x0, x1), (y0, y1) = self.x_range, self.y_range
        (u0, u1), (v0, v1) = self.surface.domain
        u = u0 + (u1 - u0) * np.clip((np.asarray(x, dtype=float) - x0) / (x1 - x0), 0.0, 1.0)
        v = v0 + (v1 - v0) * np.clip((np.asarray(y, dtype=float) - y0) / (y1 - y0), 0.0, 1.0)
        return self.surface.evaluate(u, v)[..., 2]


def height_field(z_ctrl, x_range, y_range, degree: int = 3) -> HeightField:
    """A height-field B-spline over a rectangle from a grid of control heights.

    Parameters
    ----------
    z_ctrl : array_like, shape (nu, nv)
        Heights of the control points; ``x`` runs along the first axis.
    x_range, y_range : (float, float)
        The planform rectangle.
    degree : int
        Degree in both directions (lowered to ``n - 1`` for short nets).
    """
    z = np.asarray(z_ctrl, dtype=float)
    if z.ndim != 2 or min(z.shape) < 2:
        raise ModelError(f"height field: control heights must be a 2-D grid of at least 2 x 2, got {z.shape}")
    nu, nv = z.shape
    pu, pv = min(degree, nu - 1), min(degree, nv - 1)
    ku, kv = clamped_uniform_knots(nu, pu), clamped_uniform_knots(nv, pv)
    gu, gv = greville_abscissae(ku, pu), greville_abscissae(kv, pv)
    (x0, x1), (y0, y1) = x_range, y_range
    X, Y = np.meshgrid(x0 + (x1 - x0) * gu, y0 + (y1 - y0) * gv, indexing="ij")
    P = np.stack([X, Y, z], axis=-1)
    return HeightField(BSplineSurface(P, pu, pv, ku, kv), (float(x0), float(x1)), (float(y0), float(y1)))


def dish(x_range, y_range, depth: float, n_ctrl: int = 4, degree: int = 3) -> HeightField:
    """A smooth dish hanging ``depth`` below its rim, as a B-spline height field.

    The control heights follow ``-depth * (1 - s^2) (1 - t^2) / c`` over the
    normalised planform coordinates ``s, t`` in [-1, 1], scaled so the centre
    of the surface is ``depth`` below the rim (which stays at zero).
    """
    nu = max(int(n_ctrl), 2)
    pu = min(degree, nu - 1)
    k = clamped_uniform_knots(nu, pu)
    g = 2.0 * greville_abscissae(k, pu) - 1.0
    S, T = np.meshgrid(g, g, indexing="ij")
    hf = height_field(-(1 - S**2) * (1 - T**2), x_range, y_range, degree)
    centre = hf.z(0.5 * sum(x_range), 0.5 * sum(y_range))
    scale = depth / max(-float(np.ravel(centre)[0]), 1e-300)
    hf.surface.control_points[..., 2] *= scale
    return hf
