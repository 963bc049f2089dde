"""Vector algebra on component-major arrays (vectors (3, h), matrices (3, 3, h)): every operation runs over all
hinges of the rod effects on contiguous memory, the hinge index last."""

from __future__ import annotations

import numpy as np


def cross(a: np.ndarray, b: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """Cross products of vectors (3, h)."""
    out = np.empty(np.broadcast_shapes(a.shape, b.shape)) if out is None else out
    np.subtract(a[1] * b[2], a[2] * b[1], out=out[0])
    np.subtract(a[2] * b[0], a[0] * b[2], out=out[1])
    np.subtract(a[0] * b[1], a[1] * b[0], out=out[2])
    return out


def inner(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Dot products over the component axis, the second to last: vectors (3, h) or stacks (n, 3, h)."""
    return np.einsum("...ih,...ih->...h", a, b)


def outer(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a b^T`` for stacks of vectors ``(k, h)`` and ``(m, h)``: shape ``(k, m, h)``."""
    return a[:, None] * b[None]


def add_diagonal(M: np.ndarray, d: np.ndarray) -> None:
    """``M += d I`` in place; ``M`` (3, 3, h), ``d`` (h,)."""
    for i in range(3):
        M[i, i] += d


def project(v: np.ndarray, t: np.ndarray, inv_l: np.ndarray) -> np.ndarray:
    """``P v / l`` with ``P = I - t t^T``: a derivative over a tangent carried to its edge vector."""
    return (v - inner(v, t) * t) * inv_l


def subtract_curvature(U: np.ndarray, t: np.ndarray, g: np.ndarray, scale: np.ndarray) -> None:
    """``U -= scale W`` with ``W = t g^T + (g . t) (I / 2 - 3/2 t t^T)`` (the normalisation's own term)."""
    gt = inner(g, t)
    U -= outer(scale * t, g - (1.5 * gt) * t)
    add_diagonal(U, -0.5 * scale * gt)


def view(a: np.ndarray, shape: tuple) -> np.ndarray:
    """``a`` with another shape, as a view (never a copy: results are written to it)."""
    return np.reshape(a, shape, copy=False)
