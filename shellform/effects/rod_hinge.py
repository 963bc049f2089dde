"""Exact gradients and Hessians of the bending and twisting energies of rod hinges.

A *hinge* is an interior node ``x_1`` of a rod with its two edges
``e^0 = x_1 - x_0`` and ``e^1 = x_2 - x_1`` and their twist angles
``theta^0, theta^1``: a stencil of 11 DOFs ``(x_0, x_1, x_2, theta^0, theta^1)``.

Both energies depend on the positions only through the unit tangents
``t^j = e^j / l^j`` (the rest Voronoi length is a constant). Their derivatives
are written over ``z = (e^0, e^1, theta^0, theta^1)`` in closed form, and
carried to the stencil DOFs by differences of node blocks
(:func:`stencil_gradient`, :func:`stencil_hessian`): ``e^0 = x_1 - x_0`` and
``e^1 = x_2 - x_1``, so no matrix product is needed for that step.

The chain rule through the normalisation ``t = e / l``, with the projector
``P = I - t t^T``, is

    dF/de = P g / l,
    d2F/de_a de_b = P_a H_ab P_b / (l_a l_b) - delta_ab (W_a + W_a^T) / l_a^2,
    W = t g^T + (g . t) (I / 2 - 3/2 t t^T),

``g`` and ``H`` the derivatives over the tangents taken as free 3-vectors (any
smooth extension off the unit sphere gives the same result once composed with
the normalisation). Every term of the hinge Hessians over the tangents is an
outer product of two vectors, a multiple of the identity or a cross-product
matrix, so the projections are applied to vectors, and the products
``P_0 M P_1`` of the off-diagonal blocks are expanded into outer products.

Array layout: the closed-form functions work on *component-major* arrays with
the hinge index last (vectors ``(3, h)``, Hessians ``(8, 8, h)``), so that every
arithmetic operation runs over all hinges on contiguous memory; the effects'
Hessian patterns follow the same order (entry-major, ``(11, 11, h)``). The
layered dense form of the same derivatives (over the tangents, then through
dense 0/+-1 maps) serves as the reference in the tests.

Conventions (Bergou et al. 2008): curvature binormal
``kb = 2 t^0 x t^1 / (1 + t^0 . t^1)``; material curvature of edge ``j`` at the
hinge ``omega^j = (kb . m2^j, -kb . m1^j)``; twist
``tau = theta^1 - theta^0 + m`` with ``m`` the reference twist
(:mod:`shellform.effects.rod_kinematics`).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .base import Effect
from .rod_kinematics import dot, skew

_I3 = np.eye(3)


# -- component-major vector algebra (vectors (3, h), matrices (3, 3, h)) --------------------


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    np.subtract(a[1] * b[2], a[2] * b[1], out=out[0])
    np.subtract(a[2] * b[0], a[0] * b[2], out=out[1])
    np.subtract(a[0] * b[1], a[1] * b[0], out=out[2])
    return out


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _outer(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a b^T`` for stacks of vectors ``(k, h)`` and ``(m, h)``: shape ``(k, m, h)``."""
    return a[:, None] * b[None]


def _add_skew(M: np.ndarray, a: np.ndarray) -> None:
    """``M += [a]_x`` (the cross-product matrix of ``a``) in place; ``M`` (3, 3, h)."""
    M[0, 1] -= a[2]
    M[0, 2] += a[1]
    M[1, 0] += a[2]
    M[1, 2] -= a[0]
    M[2, 0] -= a[1]
    M[2, 1] += a[0]


def _add_diagonal(M: np.ndarray, d: np.ndarray) -> None:
    """``M += d I`` in place; ``M`` (3, 3, h), ``d`` (h,)."""
    for i in range(3):
        M[i, i] += d


def _project(v: np.ndarray, t: np.ndarray, inv_l: np.ndarray) -> np.ndarray:
    """``P v / l`` with ``P = I - t t^T``: a derivative over a tangent carried to its edge vector."""
    return (v - _dot(v, t) * t) * inv_l


def _subtract_curvature(U: np.ndarray, t: np.ndarray, g: np.ndarray, scale: np.ndarray) -> None:
    """``U -= scale W`` with ``W = t g^T + (g . t) (I / 2 - 3/2 t t^T)`` (the normalisation's own term)."""
    gt = _dot(g, t)
    U -= _outer(scale * t, g - (1.5 * gt) * t)
    _add_diagonal(U, -0.5 * scale * gt)


# -- the material-frame terms of curved and anisotropic hinges, over the tangents -------


class BinormalJacobian(NamedTuple):
    """The curvature binormal of each hinge with the quantities its derivatives are built from.

    Attributes
    ----------
    kb : ndarray (n, 3)
    chi : ndarray (n,)
        ``1 + t0 . t1``.
    J : ndarray (n, 3, 6)
        ``d kb / d(t0, t1)``.
    """

    kb: np.ndarray
    chi: np.ndarray
    J: np.ndarray


def curvature_binormal_jacobian(t0: np.ndarray, t1: np.ndarray) -> BinormalJacobian:
    """Curvature binormal and its Jacobian with respect to ``(t0, t1)``."""
    chi = 1.0 + dot(t0, t1)
    kb = 2.0 * np.cross(t0, t1) / chi[:, None]
    J = np.empty((len(t0), 3, 6))
    J[:, :, :3] = (-2.0 * skew(t1) - kb[:, :, None] * t1[:, None, :]) / chi[:, None, None]
    J[:, :, 3:] = (2.0 * skew(t0) - kb[:, :, None] * t0[:, None, :]) / chi[:, None, None]
    return BinormalJacobian(kb, chi, J)


def hessian_of_projected_binormal(t0, t1, kb, chi, J, p):
    """Hessian over ``(t0, t1)`` of ``h = p . kb`` for a fixed vector ``p``; shape (n, 6, 6).

    From ``h chi = 2 p . (t0 x t1)``:
    ``H_h = (2 H_N - grad h grad chi^T - grad chi grad h^T - h H_chi) / chi``.
    """
    n = len(t0)
    h = dot(p, kb)
    gh = np.einsum("nk,nka->na", p, J)
    gchi = np.concatenate([t1, t0], axis=1)
    P = skew(p)
    H = np.zeros((n, 6, 6))
    H[:, :3, 3:] = -2.0 * P
    H[:, 3:, :3] = 2.0 * P
    H -= gh[:, :, None] * gchi[:, None, :] + gchi[:, :, None] * gh[:, None, :]
    H[:, :3, 3:] -= h[:, None, None] * _I3
    H[:, 3:, :3] -= h[:, None, None] * _I3
    return H / chi[:, None, None]





def _transported_components(abc):
    """Parallel-transported directors in the stored frame, with first and second derivatives.

    With ``(a, b, c)`` the components of a tangent in the stored frame
    ``(u, v, s)`` of its edge, the transported directors have components
    ``U = (c + b^2/d, -ab/d, -a)`` and ``V = (-ab/d, c + a^2/d, -b)``,
    ``d = 1 + c``.

    Returns
    -------
    U, V : (n, 3)
    DU, DV : (n, 3, 3)   d(component)/d(a, b, c)
    HU, HV : (n, 3, 3, 3) second derivatives, indexed [component, var, var]
    """
    a, b, c = abc[:, 0], abc[:, 1], abc[:, 2]
    n = len(a)
    d = 1.0 + c
    d2, d3 = d * d, d * d * d
    U = np.stack([c + b * b / d, -a * b / d, -a], axis=1)
    V = np.stack([-a * b / d, c + a * a / d, -b], axis=1)
    DU = np.zeros((n, 3, 3))
    DV = np.zeros((n, 3, 3))
    DU[:, 0, 1] = 2 * b / d
    DU[:, 0, 2] = 1 - b * b / d2
    DU[:, 1, 0] = -b / d
    DU[:, 1, 1] = -a / d
    DU[:, 1, 2] = a * b / d2
    DU[:, 2, 0] = -1.0
    DV[:, 0] = DU[:, 1]
    DV[:, 1, 0] = 2 * a / d
    DV[:, 1, 2] = 1 - a * a / d2
    DV[:, 2, 1] = -1.0
    HU = np.zeros((n, 3, 3, 3))
    HV = np.zeros((n, 3, 3, 3))
    HU[:, 0, 1, 1] = 2 / d
    HU[:, 0, 1, 2] = HU[:, 0, 2, 1] = -2 * b / d2
    HU[:, 0, 2, 2] = 2 * b * b / d3
    HU[:, 1, 0, 1] = HU[:, 1, 1, 0] = -1 / d
    HU[:, 1, 0, 2] = HU[:, 1, 2, 0] = b / d2
    HU[:, 1, 1, 2] = HU[:, 1, 2, 1] = a / d2
    HU[:, 1, 2, 2] = -2 * a * b / d3
    HV[:, 0] = HU[:, 1]
    HV[:, 1, 0, 0] = 2 / d
    HV[:, 1, 0, 2] = HV[:, 1, 2, 0] = -2 * a / d2
    HV[:, 1, 2, 2] = 2 * a * a / d3
    return U, V, DU, DV, HU, HV


def material_curvature_value(kb, t_edge, frame, omega_bar, theta):
    """``omega_bar . omega^j`` alone (no derivatives), for energy evaluations."""
    ct, st = np.cos(theta), np.sin(theta)
    w1, w2 = omega_bar[:, 0], omega_bar[:, 1]
    A = -w1 * st - w2 * ct
    B = w1 * ct - w2 * st
    a, b, c = np.einsum("nia,ni->na", frame, t_edge).T
    d = 1.0 + c
    U = np.stack([c + b * b / d, -a * b / d, -a], axis=1)
    V = np.stack([-a * b / d, c + a * a / d, -b], axis=1)
    p = np.einsum("nia,ni->na", frame, kb)
    return dot(p, A[:, None] * U + B[:, None] * V)


def material_curvature_term(t0, t1, binormal: BinormalJacobian, edge, frame, omega_bar, theta):
    """Value and derivatives over ``y = (t0, t1, theta0, theta1)`` of ``omega_bar . omega^j``.

    ``omega_bar . omega^j = kb . W`` with ``W = omega_bar_1 m2 - omega_bar_2 m1``,
    a vector fixed in the material frame of edge ``j``.

    Parameters
    ----------
    t0, t1 : (n, 3)
        Tangents of the edges at the trial state.
    binormal : BinormalJacobian
        Of ``t0, t1`` (:func:`curvature_binormal_jacobian`).
    edge : {0, 1}
        Which edge of the hinge.
    frame : (n, 3, 3)
        Stored frame of that edge, columns ``(u, v, s)``.
    omega_bar : (n, 2)
        Natural material curvature of the hinge in that edge's frame.
    theta : (n,)
        Twist angle of that edge.

    Returns
    -------
    f : (n,), g : (n, 8), H : (n, 8, 8)
    """
    n = len(t0)
    kb, chi, J = binormal
    t_edge = (t0, t1)[edge]
    ct, st = np.cos(theta), np.sin(theta)
    w1, w2 = omega_bar[:, 0], omega_bar[:, 1]
    A = -w1 * st - w2 * ct  # coefficient of u in W
    B = w1 * ct - w2 * st  # coefficient of v in W (dA/dtheta = -B, dB/dtheta = A)
    abc = np.einsum("nia,ni->na", frame, t_edge)
    U, V, DU, DV, HU, HV = _transported_components(abc)
    w = A[:, None] * U + B[:, None] * V
    w_th = -B[:, None] * U + A[:, None] * V
    Dw = A[:, None, None] * DU + B[:, None, None] * DV
    Dw_th = -B[:, None, None] * DU + A[:, None, None] * DV
    p = np.einsum("nia,ni->na", frame, kb)  # kb in the stored frame of the edge
    W = np.einsum("nia,na->ni", frame, w)
    W_th = np.einsum("nia,na->ni", frame, w_th)

    f = dot(p, w)
    te = slice(3 * edge, 3 * edge + 3)
    th = 6 + edge
    g = np.zeros((n, 8))
    g[:, :6] = np.einsum("nk,nka->na", W, J)
    g[:, te] += np.einsum("nab,nb->na", frame, np.einsum("nka,nk->na", Dw, p))
    g[:, th] = dot(p, w_th)

    H = np.zeros((n, 8, 8))
    H[:, :6, :6] = hessian_of_projected_binormal(t0, t1, kb, chi, J, W)
    # d/dt_edge of W, in global coordinates: frame Dw frame^T
    dW = np.einsum("nia,nab,njb->nij", frame, Dw, frame)
    cross = np.einsum("nki,nkj->nij", J, dW)  # (n, 6, 3)
    H[:, :6, te] += cross
    H[:, te, :6] += np.swapaxes(cross, 1, 2)
    curv = np.einsum("nk,nkab->nab", p, A[:, None, None, None] * HU + B[:, None, None, None] * HV)
    H[:, te, te] += np.einsum("nia,nab,njb->nij", frame, curv, frame)
    mixed = np.einsum("nki,nk->ni", J, W_th)
    mixed[:, te] += np.einsum("nab,nb->na", frame, np.einsum("nka,nk->na", Dw_th, p))
    H[:, :6, th] = mixed
    H[:, th, :6] = mixed
    H[:, th, th] = -f
    return f, g, H




# -- the isotropic bending term |kb|^2 over the edge vectors -------------------------------


def binormal_energy_derivatives(t0, t1, l0, l1, order=2, scale=None, out=None):
    """``|kb|^2`` and its gradient (6, h) and Hessian (6, 6, h) over ``(e^0, e^1)``.

    With ``chi = 1 + t0 . t1``, ``w = t0 + t1`` and ``S_a = [t_a]_x``, the
    Jacobian of the binormal over the edge vectors is
    ``K = [(-2 S_1 - kb w^T) / (chi l0), (2 S_0 - kb w^T) / (chi l1)]``, so that
    ``grad = 2 K^T kb``. The Hessian is ``2 (K^T K + sum_k kb_k Hess kb_k)``,
    written as ``2 (U + U^T)`` with ``U`` collected below: two outer products
    of 6-vectors and, per 3 x 3 block, outer products of 3-vectors, multiples
    of the identity and one cross-product matrix.

    Parameters
    ----------
    t0, t1 : (3, h)
        Unit tangents of the two edges.
    l0, l1 : (h,)
        Their lengths.
    order : {0, 1, 2}
    scale : (h,), optional
        Factor of the gradient and Hessian of each hinge (the energy is not scaled).
    out : (6, 6, h), optional
        Where to write the Hessian.

    Returns
    -------
    f : (h,), and for ``order >= 1`` grad : (6, h), for ``order == 2`` hess : (6, 6, h)
    """
    chi = 1.0 + _dot(t0, t1)
    ichi = 1.0 / chi
    kb = (2.0 * ichi) * _cross(t0, t1)
    kk = _dot(kb, kb)
    if order == 0:
        return (kk,)
    s2 = 2.0 if scale is None else 2.0 * scale
    i0, i1 = 1.0 / l0, 1.0 / l1
    a0 = 2.0 * _cross(t1, kb)  # -2 S_1^T kb
    a1 = 2.0 * _cross(kb, t0)  # 2 S_0^T kb
    w = t0 + t1
    kw = kk * w
    gh = np.empty((6,) + kk.shape)  # K^T kb
    np.multiply(a0 - kw, ichi * i0, out=gh[:3])
    np.multiply(a1 - kw, ichi * i1, out=gh[3:])
    if order == 1:
        return kk, s2 * gh
    v = np.empty_like(gh)  # (w / l0, w / l1)
    np.multiply(w, i0, out=v[:3])
    np.multiply(w, i1, out=v[3:])
    nu = v.copy()  # v + grad of chi over the edges
    nu[:3] += (t1 - (chi - 1.0) * t0) * i0
    nu[3:] += (t0 - (chi - 1.0) * t1) * i1
    # K^T K = (L^T L - chi (gh v^T + v gh^T) - kk v v^T) / chi^2 with L = [-2 S_1 / l0, 2 S_0 / l1];
    # the binormal's curvature adds -(gh g_chi^T + g_chi gh^T) / chi and the blocks below
    ichi2 = ichi * ichi
    U = _outer((-s2 * ichi) * gh, nu)
    U -= _outer((0.5 * s2 * kk * ichi2) * v, v)
    # diagonal blocks: L^T L / 2 = 2 (I - t_b t_b^T) / l_a^2, and the normalisation terms (g . t = kk / chi)
    for a, (ta, tb, ia, aa) in enumerate(((t0, t1, i0, a0), (t1, t0, i1, a1))):
        sl = slice(3 * a, 3 * a + 3)
        Uaa = U[sl, sl]
        ia2 = s2 * ia * ia
        Uaa -= _outer((2.0 * ichi2 * ia2) * tb, tb)
        # W_a with the tangent-space gradient (aa - kk t_b) / chi of kb . kb / 2
        Uaa -= _outer((ichi * ia2) * ta, aa - kk * tb - (1.5 * kk) * ta)
        _add_diagonal(Uaa, (2.0 * ichi2 - 0.5 * kk * ichi) * ia2)
    # off-diagonal block: 4 (t0 t1^T - (t0.t1) I) / (chi^2 l0 l1) - P0 (2 [kb]_x + kk I) P1 / (chi l0 l1)
    alpha = s2 * ichi * i0 * i1
    U01 = U[:3, 3:]
    U01 += _outer(alpha * t0, kk * t0 + (4.0 * ichi + kk) * t1 - a1)
    U01 += _outer(alpha * (kk * t1 - a0), t1)
    _add_skew(U01, -2.0 * alpha * kb)
    _add_diagonal(U01, -alpha * (4.0 * (chi - 1.0) * ichi + kk))
    H = np.add(U, U.swapaxes(0, 1), out=out)
    return kk, s2 * gh, H


# -- the reference twist over the edge vectors ----------------------------------------------


class TwistTerms(NamedTuple):
    """The reference-twist change and what its Hessian is built from (component-major arrays)."""

    beta: np.ndarray
    grad: np.ndarray  # (6, h) over the edge vectors
    grad_t: np.ndarray  # (6, h) over the tangents
    parts: tuple | None


def reference_twist_derivatives(t0, t1, l0, l1, s0, s1, order=2) -> TwistTerms:
    """Change of the reference twist from the stored state, with its gradient over ``(e^0, e^1)``.

    ``beta = -Omega(s0, t0, t1) - Omega(s0, t1, s1)`` (see
    :mod:`shellform.effects.rod_kinematics`), so that ``m(q) = m_stored + beta``;
    ``Omega = 2 atan2(N, D)`` with ``N`` and ``D`` bilinear (first triangle) or
    linear (second) in the tangents. For ``order == 2`` the returned ``parts``
    feed :func:`reference_twist_hessian`.
    """
    gN1 = np.empty((6,) + l0.shape)
    gN1[:3] = _cross(t1, s0)
    gN1[3:] = _cross(s0, t0)
    N1 = _dot(t0, gN1[:3])  # s0 . (t0 x t1)
    D1 = 1.0 + _dot(t0, t1) + _dot(s0, t0 + t1)
    gD1 = np.empty_like(gN1)
    np.add(s0, t1, out=gD1[:3])
    np.add(s0, t0, out=gD1[3:])
    R1 = N1 * N1 + D1 * D1
    G1 = D1 * gN1
    G1 -= N1 * gD1
    gN2 = _cross(s1, s0)
    N2 = _dot(t1, gN2)  # s0 . (t1 x s1)
    gD2 = s0 + s1
    D2 = 1.0 + _dot(gD2, t1) + _dot(s1, s0)
    R2 = N2 * N2 + D2 * D2
    G2 = D2 * gN2 - N2 * gD2
    beta = -2.0 * (np.arctan2(N1, D1) + np.arctan2(N2, D2))
    gt = (-2.0 / R1) * G1
    gt[3:] -= (2.0 / R2) * G2
    i0, i1 = 1.0 / l0, 1.0 / l1
    g = np.empty_like(gt)
    g[:3] = _project(gt[:3], t0, i0)
    g[3:] = _project(gt[3:], t1, i1)
    parts = None
    if order == 2:
        parts = (N1, D1, R1, G1, gN1, gD1, N2, D2, R2, G2, gN2, gD2, i0, i1)
    return TwistTerms(beta, g, gt, parts)


def reference_twist_hessian(t0, t1, s0, terms: TwistTerms, c, k, out=None) -> np.ndarray:
    """``c Hess(beta) + 2 k grad(beta) grad(beta)^T`` over ``(e^0, e^1)``, shape (6, 6, h).

    The Hessian of ``2 atan2(N, D)`` over the tangents is
    ``2 (D H_N - N H_D) / R - (G g_R^T + g_R G^T) / R^2`` with
    ``R = N^2 + D^2``, ``G = D g_N - N g_D``, ``g_R = 2 (N g_N + D g_D)``
    (the antisymmetric part of ``grad G`` cancels). For the first triangle
    ``H_N = [[0, -S], [S, 0]]`` (``S = [s0]_x``) and ``H_D = [[0, I], [I, 0]]``;
    the second has ``H_N = H_D = 0``.
    """
    N1, D1, R1, G1, gN1, gD1, N2, D2, R2, G2, gN2, gD2, i0, i1 = terms.parts
    g = terms.grad
    chi1 = _dot(t0, t1)
    # the rank-one terms, with their vectors carried to the edges
    a = np.empty((6,) + i0.shape)
    b = np.empty_like(a)
    cR = c / (R1 * R1)
    a[:3] = _project(G1[:3], t0, cR * i0)
    a[3:] = _project(G1[3:], t1, cR * i1)
    gR1 = N1 * gN1
    gR1 += D1 * gD1
    b[:3] = _project(gR1[:3], t0, 2.0 * i0)
    b[3:] = _project(gR1[3:], t1, 2.0 * i1)
    U = _outer(k * g, g)
    U += _outer(a, b)
    U[3:, 3:] += _outer(_project(G2, t1, (c / (R2 * R2)) * i1), _project(N2 * gN2 + D2 * gD2, t1, 2.0 * i1))
    # off-diagonal block of the first triangle: 2 c P0 (D1 [s0]_x + N1 I) P1 / (R1 l0 l1)
    alpha = 2.0 * c * i0 * i1 / R1
    U01 = U[:3, 3:]
    # P0 M P1 = M - t0 (M^T t0)^T - (M t1) t1^T + (t0^T M t1) t0 t1^T,
    # M^T t0 = N1 t0 - D1 (s0 x t0), M t1 = N1 t1 - D1 (t1 x s0), t0^T M t1 = N1 (t0.t1 - D1)
    U01 -= _outer(alpha * t0, N1 * t0 - D1 * gN1[3:] - (N1 * (chi1 - D1)) * t1)
    U01 -= _outer(alpha * (N1 * t1 - D1 * gN1[:3]), t1)
    _add_skew(U01, (alpha * D1) * s0)
    _add_diagonal(U01, alpha * N1)
    # the normalisation's terms on the diagonal blocks
    gt = terms.grad_t
    _subtract_curvature(U[:3, :3], t0, gt[:3], c * i0 * i0)
    _subtract_curvature(U[3:, 3:], t1, gt[3:], c * i1 * i1)
    return np.add(U, U.swapaxes(0, 1), out=out)


# -- from the edge vectors to the stencil -----------------------------------------------------


def project_to_edges(t0, t1, l0, l1, g, H=None):
    """Carry a gradient (8, h) and Hessian (8, 8, h) over ``(t0, t1, theta0, theta1)`` to ``z``.

    The general form of the chain rule through the normalisation, for terms
    given over the tangents (the material-frame terms of curved and
    anisotropic hinges).
    """
    i0, i1 = 1.0 / l0, 1.0 / l1
    gz = g.copy()
    gz[:3] = _project(g[:3], t0, i0)
    gz[3:6] = _project(g[3:6], t1, i1)
    if H is None:
        return gz, None
    Hz = H.copy()
    for a, t in enumerate((t0, t1)):
        s = slice(3 * a, 3 * a + 3)
        Hz[:, s] -= _outer((Hz[:, s] * t).sum(axis=1), t)
        Hz[s] -= _outer(t, (Hz[s] * t[:, None]).sum(axis=0))
    scale = np.ones_like(g)
    scale[:3] = i0
    scale[3:6] = i1
    Hz *= _outer(scale, scale)
    for a, (t, ia) in enumerate(((t0, i0), (t1, i1))):
        s = slice(3 * a, 3 * a + 3)
        W = np.zeros((3, 3) + i0.shape)
        _subtract_curvature(W, t, g[s], -ia * ia)
        Hz[s, s] -= W + W.swapaxes(0, 1)
    return gz, Hz


def stencil_gradient(gz: np.ndarray) -> np.ndarray:
    """Gradient over the stencil DOFs (11, h) from one over ``z`` (8, h): ``e^0 = x1 - x0``, ``e^1 = x2 - x1``."""
    g = np.empty((11,) + gz.shape[1:])
    np.negative(gz[:3], out=g[:3])
    np.subtract(gz[:3], gz[3:6], out=g[3:6])
    g[6:9] = gz[3:6]
    g[9:] = gz[6:]
    return g


def stencil_hessian(Hz: np.ndarray) -> np.ndarray:
    """Hessian over the stencil DOFs (11, 11, h) from a symmetric one over ``z`` (8, 8, h).

    With the blocks ``A = H_{e0 e0}``, ``B = H_{e0 e1}``, ``C = H_{e1 e1}``,
    ``a = H_{e0 theta}``, ``c = H_{e1 theta}``: ``x0 x0: A``, ``x0 x1: B - A``,
    ``x0 x2: -B``, ``x1 x1: A - B - B^T + C``, ``x1 x2: B - C``, ``x2 x2: C``,
    ``x0 theta: -a``, ``x1 theta: a - c``, ``x2 theta: c``; the lower blocks
    are the transposes.
    """
    H = np.empty((11, 11) + Hz.shape[2:])
    A, B, C = Hz[:3, :3], Hz[:3, 3:6], Hz[3:6, 3:6]
    a, c = Hz[:3, 6:], Hz[3:6, 6:]
    H[:3, :3] = A
    np.subtract(B, A, out=H[:3, 3:6])
    np.negative(B, out=H[:3, 6:9])
    x11 = H[3:6, 3:6]
    np.subtract(A, B, out=x11)
    x11 -= B.swapaxes(0, 1)
    x11 += C
    np.subtract(B, C, out=H[3:6, 6:9])
    H[6:9, 6:9] = C
    np.negative(a, out=H[:3, 9:])
    np.subtract(a, c, out=H[3:6, 9:])
    H[6:9, 9:] = c
    H[9:, 9:] = Hz[6:, 6:]
    H[3:6, :3] = H[:3, 3:6].swapaxes(0, 1)
    H[6:9, :6] = H[:6, 6:9].swapaxes(0, 1)
    H[9:, :9] = H[:9, 9:].swapaxes(0, 1)
    return H


def stencil_pattern(stencil: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """COO pattern of the stencil Hessians in the order of a C-contiguous ``(11, 11, h)`` value array."""
    s = np.ascontiguousarray(stencil.T)  # (11, h)
    k, h = s.shape
    rows = np.broadcast_to(s[:, None, :], (k, k, h)).ravel()
    cols = np.broadcast_to(s[None, :, :], (k, k, h)).ravel()
    return rows.astype(np.int64), cols.astype(np.int64)


# -- common machinery of the hinge effects ------------------------------------------------


class HingeEffect(Effect):
    """Base of the effects defined on rod hinges (11-DOF stencils) with shared reference frames.

    The energy of hinge ``i`` is ``k_i f_i`` with ``k_i = stiffness_i / (2 dl_i)``.
    Subclasses implement ``_local(q, order)`` returning the energy per hinge
    (h,) and, for ``order >= 1``, its gradient (8, h) and, for ``order == 2``,
    Hessian (8, 8, h) over ``z = (e0, e1, theta0, theta1)`` (component-major).

    Parameters
    ----------
    n_dof : int
    frames : ReferenceFrames
        Shared reference state of the rod edges.
    stencil : ndarray (h, 11)
        DOFs ``(x0, x1, x2, theta0, theta1)`` of every hinge.
    voronoi : ndarray (h,)
        Rest Voronoi lengths ``dl`` [m].
    stiffness : ndarray (h,)
        Bending or torsional stiffness [N m^2].
    """

    def __init__(self, n_dof, frames, stencil, voronoi, stiffness):
        super().__init__(n_dof)
        self.frames = frames
        self.stencil = np.asarray(stencil, dtype=np.int64)
        self.hinge_edges = frames.hinges
        self._dofs_t = np.ascontiguousarray(self.stencil.T)
        self._pattern = stencil_pattern(self.stencil)
        self.voronoi = np.asarray(voronoi, dtype=float)
        self.k = np.asarray(stiffness, dtype=float) / (2.0 * self.voronoi)

    def _geometry(self, q):
        """Tangents (3, h) and lengths (h,) of both edges of every hinge, and the twist angles (2, h)."""
        t0, t1, l0, l1 = self.frames.hinge_tangents(q)
        return t0, t1, l0, l1, q[self._dofs_t[9:]]

    def energy(self, q):
        return float(np.sum(self._local(q, 0)[0]))

    def _stencil_forces(self, q):
        """Gradient of every hinge's energy on its 11 stencil DOFs, shape (11, h)."""
        return stencil_gradient(self._local(q, 1)[1])

    def gradient(self, q):
        return np.bincount(self._dofs_t.ravel(), weights=self._stencil_forces(q).ravel(), minlength=self.n_dof)

    def force_magnitudes(self, q):
        return np.bincount(self._dofs_t.ravel(), weights=np.abs(self._stencil_forces(q)).ravel(),
                           minlength=self.n_dof)

    def hessian_pattern(self):
        return self._pattern

    def hessian_values(self, q):
        return stencil_hessian(self._local(q, 2)[2]).ravel()

    def accept(self, q: np.ndarray) -> None:
        """Make ``q`` the stored reference state (time-parallel transport of the frames)."""
        self.frames.update(q)
