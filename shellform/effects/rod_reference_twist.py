"""The change of the reference twist at every hinge and its derivatives over the edge vectors, in closed form.

``beta = m(q) - m_stored`` from the spherical-triangle (solid angle) expressions of
:mod:`shellform.effects.rod_kinematics`, with its gradient over ``(e^0, e^1)`` and its
Hessian added to a :class:`~shellform.effects.rod_stencil.HingeHessian` as rank-one and
cross-product terms. Component-major arrays, the hinge index last.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from .rod_vectors import cross, inner, view

if TYPE_CHECKING:  # the collector the Hessian terms are added to; it imports this module
    from .rod_stencil import HingeHessian


class TwistTerms(NamedTuple):
    """The reference-twist change and what its Hessian is built from (component-major arrays)."""

    beta: np.ndarray
    grad: np.ndarray  # (6, h) over the edge vectors
    grad_t: np.ndarray  # (6, h) over the tangents
    parts: tuple | None


class TwistInputs(NamedTuple):
    """What the twisting Hessian of every hinge takes besides its tangents and lengths, for the compiled kernel
    (:mod:`.rod_compiled`)."""

    k: np.ndarray  # (h,) GJ / (2 dl)
    s0: np.ndarray  # (3, h) stored tangents of the two edges
    s1: np.ndarray
    n2: np.ndarray  # (3, h) s1 x s0
    d2: np.ndarray  # (3, h) s0 + s1
    s1s0: np.ndarray  # (h,) s1 . s0
    twist: np.ndarray  # (h,) stored reference twist
    tau_bar: np.ndarray  # (h,) natural twist


def stored_twist_terms(s0, s1) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """What the second triangle of the reference twist takes from the stored tangents alone:
    ``s1 x s0``, ``s0 + s1`` (3, h) and ``s1 . s0`` (h,)."""
    return cross(s1, s0), s0 + s1, inner(s1, s0)


def reference_twist_derivatives(t0, t1, l0, l1, s0, s1, order=2, T=None, inv=None, stored=None) -> TwistTerms:
    """Change of the reference twist from the stored state, with its gradient over ``(e^0, e^1)``.

    ``beta = -Omega(s0, t0, t1) - Omega(s0, t1, s1)`` (see
    :mod:`shellform.effects.rod_kinematics`), so that ``m(q) = m_stored + beta``;
    ``Omega = 2 atan2(N, D)`` with ``N`` and ``D`` bilinear (first triangle) or
    linear (second) in the tangents. For ``order == 2`` the returned ``parts``
    feed :func:`reference_twist_hessian`. ``T`` (2, 3, h) and ``inv`` (2, h),
    the tangents and inverse lengths stacked, and ``stored``
    (:func:`stored_twist_terms`) are computed unless given.
    """
    if T is None:
        T = np.stack((t0, t1))
        inv = 1.0 / np.stack((l0, l1))
    # t1 x s0 and s0 x t0 (the gradient of N1 over the tangents) and s1 x s0 (that of N2 over t1)
    gN1 = np.empty_like(T)
    cross(t1, s0, out=gN1[0])
    cross(s0, t0, out=gN1[1])
    gN2, gD2, s1s0 = stored_twist_terms(s0, s1) if stored is None else stored
    # N1 = s0 . (t0 x t1), D1 = 1 + t0 . t1 + s0 . (t0 + t1); N2 = s0 . (t1 x s1), D2 = 1 + (s0 + s1) . t1 + s1 . s0
    N1, N2 = inner(t0, gN1[0]), inner(t1, gN2)
    s0t1 = inner(s0, t1)
    D1 = 1.0 + inner(t0, t1) + inner(s0, t0) + s0t1
    gD1 = s0 + T[::-1]
    R1 = N1 * N1 + D1 * D1
    G1 = D1 * gN1
    G1 -= N1 * gD1
    D2 = 1.0 + s0t1 + inner(s1, t1) + s1s0
    R2 = N2 * N2 + D2 * D2
    G2 = D2 * gN2 - N2 * gD2
    beta = -2.0 * (np.arctan2(N1, D1) + np.arctan2(N2, D2))
    gt = (-2.0 / R1) * G1
    gt[1] -= (2.0 / R2) * G2
    gtt = inner(gt, T)
    g = gt - gtt[:, None] * T
    g *= inv[:, None]
    parts = None
    if order == 2:
        parts = (N1, D1, R1, gN1, gD1, N2, D2, R2, G2, gN2, gD2, gtt)
    return TwistTerms(beta, view(g, (6, -1)), view(gt, (6, -1)), parts)


def reference_twist_hessian(acc: HingeHessian, s0, terms: TwistTerms, c, k) -> None:
    """Add ``c Hess(beta) + 2 k grad(beta) grad(beta)^T`` over ``(e^0, e^1)`` to ``acc`` (two slots of its own).

    The Hessian of ``2 atan2(N, D)`` over the tangents is
    ``2 (D H_N - N H_D) / R - (G g_R^T + g_R G^T) / R^2`` with
    ``R = N^2 + D^2``, ``G = D g_N - N g_D``, ``g_R = 2 (N g_N + D g_D)``
    (the antisymmetric part of ``grad G`` cancels). For the first triangle
    ``H_N = [[0, -S], [S, 0]]`` (``S = [s0]_x``) and ``H_D = [[0, I], [I, 0]]``;
    the second has ``H_N = H_D = 0``. Carried to the edges (``P_a v / l_a``,
    ``P_a = I - t_a t_a^T``), the first triangle's ``G`` is
    ``-(R1 / 2) (grad beta + (0, 2 P_1 G2 / (R2 l1)))``, so the rank-one terms
    are ``grad beta (k grad beta - c b / (2 R1))^T`` and
    ``(0, P_1 G2 / l1) (c (0, 2 P_1 (N2 g_N2 + D2 g_D2) / l1) / R2^2 - c b / (R1 R2))^T``
    with ``b = (P_0 g_R1 / l0, P_1 g_R1 / l1)``; the off-diagonal block of the
    first triangle is ``2 c P0 (D1 [s0]_x + N1 I) P1 / (R1 l0 l1)``, and the
    normalisation adds its terms to the diagonal blocks.
    """
    N1, D1, R1, gN1, gD1, N2, D2, R2, G2, gN2, gD2, gtt = terms.parts
    T, inv = acc.T, acc.inv
    t0, t1 = T
    g = terms.grad
    # b: the gradient of R1 over the edge vectors
    gR1 = N1 * gN1
    gR1 += D1 * gD1
    b = gR1 - inner(gR1, T)[:, None] * T
    b *= (2.0 * inv)[:, None]
    b = view(b, (6, -1))
    X, Y = acc.claim()
    X[...] = g
    np.subtract(k * g, (0.5 * c / R1) * b, out=Y)
    X, Y = acc.claim()
    X[:3] = 0.0
    # P1 G2 / l1 and 2 P1 (N2 gN2 + D2 gD2) / l1
    np.multiply(G2 - inner(G2, t1) * t1, inv[1], out=X[3:])
    np.multiply(b, -c / (R1 * R2), out=Y)
    gR2 = N2 * gN2
    gR2 += D2 * gD2
    gR2 -= inner(gR2, t1) * t1
    gR2 *= (2.0 * c / (R2 * R2)) * inv[1]
    Y[3:] += gR2
    # off-diagonal block of the first triangle: P0 M P1 = M - t0 (M^T t0)^T - (M t1) t1^T + (t0^T M t1) t0 t1^T
    # for M = D1 [s0]_x + N1 I: M^T t0 = N1 t0 - D1 (s0 x t0), M t1 = N1 t1 - D1 (t1 x s0), t0^T M t1 = N1 (t0.t1 - D1)
    alpha = (2.0 * inv[0] * inv[1] / R1) * c
    aN, aD = alpha * N1, alpha * D1
    R = acc.R
    R[1:5:3] -= aN * T - aD * gN1[::-1]
    R[1] += (aN * (acc.cos - D1)) * t1
    acc.skew += aD * s0
    acc.diagonal[2] += aN
    # the normalisation: -(c / l^2) W with W = t g^T + (g . t) (I / 2 - 3/2 t t^T), g over the tangent
    sc = c * inv * inv
    R[0:6:5] -= sc[:, None] * (view(terms.grad_t, (2, 3, -1)) - (1.5 * gtt)[:, None] * T)
    acc.diagonal[:2] -= 0.5 * sc * gtt
    # tau = theta1 - theta0 + m: its gradient over z is (grad beta, -1, 1)
    k2 = 2.0 * k
    kg = k2 * g
    theta = acc.theta
    theta[:, 0] -= kg
    theta[:, 1] += kg
    acc.theta2[0:3:2] += k2
    acc.theta2[1] -= k2
