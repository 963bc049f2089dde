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
The isotropic bending and the twisting collect these terms in a
:class:`HingeHessian`, which sums the outer products of all hinges with one
batched product of small matrices and carries the sum of the effects to the
stencil once, to the upper triangle of each stencil Hessian
(:data:`UPPER_PAIRS`) for the System's tangents.

Array layout: the closed-form functions work on *component-major* arrays with
the hinge index last (vectors ``(3, h)``, Hessians ``(8, 8, h)``), so that every
arithmetic operation runs over all hinges on contiguous memory; the effects'
Hessian patterns follow the same order (entry-major, ``(11, 11, h)`` and
``(66, h)``). The layered dense form of the same derivatives (over the
tangents, then through dense 0/+-1 maps) serves as the reference in the tests.

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


def _cross(a: np.ndarray, b: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """Cross products of vectors (3, h)."""
    out = np.empty(np.broadcast_shapes(a.shape, b.shape)) if out is None else out
    np.subtract(a[1] * b[2], a[2] * b[1], out=out[0])
    np.subtract(a[2] * b[0], a[0] * b[2], out=out[1])
    np.subtract(a[0] * b[1], a[1] * b[0], out=out[2])
    return out


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Dot products over the component axis, the second to last: vectors (3, h) or stacks (n, 3, h)."""
    return np.einsum("...ih,...ih->...h", a, b)


def _outer(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a b^T`` for stacks of vectors ``(k, h)`` and ``(m, h)``: shape ``(k, m, h)``."""
    return a[:, None] * b[None]


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


def binormal_energy_derivatives(t0, t1, l0, l1, order=1, scale=None):
    """``|kb|^2`` and, for ``order == 1``, its gradient (6, h) over ``(e^0, e^1)``.

    With ``chi = 1 + t0 . t1`` and ``w = t0 + t1``, the Jacobian of the
    binormal over the edge vectors is
    ``K = [(-2 S_1 - kb w^T) / (chi l0), (2 S_0 - kb w^T) / (chi l1)]``
    (``S_a = [t_a]_x``), so that ``grad = 2 K^T kb``. The Hessian is
    collected by :func:`binormal_energy_hessian`.

    Parameters
    ----------
    t0, t1 : (3, h)
        Unit tangents of the two edges.
    l0, l1 : (h,)
        Their lengths.
    order : {0, 1}
    scale : (h,), optional
        Factor of the gradient of each hinge (the energy is not scaled).

    Returns
    -------
    f : (h,), and for ``order == 1`` grad : (6, h)
    """
    chi = 1.0 + _dot(t0, t1)
    ichi = 1.0 / chi
    kb = (2.0 * ichi) * _cross(t0, t1)
    kk = _dot(kb, kb)
    if order == 0:
        return (kk,)
    s2 = 2.0 if scale is None else 2.0 * scale
    w = t0 + t1
    kw = kk * w
    gh = np.empty((6,) + kk.shape)  # K^T kb
    np.multiply(2.0 * _cross(t1, kb) - kw, s2 * ichi / l0, out=gh[:3])
    np.multiply(2.0 * _cross(kb, t0) - kw, s2 * ichi / l1, out=gh[3:])
    return kk, gh


def binormal_energy_hessian(acc: HingeHessian, k) -> None:
    """Add the Hessian of ``k |kb|^2`` over ``(e^0, e^1)`` to ``acc`` (two slots of its own).

    The Hessian is ``2 k (K^T K + sum_k kb_k Hess kb_k)`` with ``K`` the
    binormal's Jacobian (:func:`binormal_energy_derivatives`). For unit
    tangents ``t1 x kb = 2 (t0 - c t1) / chi`` and ``kb x t0 = 2 (t1 - c t0) / chi``
    (``c = t0 . t1 = chi - 1``) and ``|kb|^2 = 4 (1 - c) / chi``, so every
    term is an outer product of combinations of ``t0`` and ``t1``, a multiple
    of the identity, or the cross-product matrix of ``t0 x t1``, itself the
    pair of outer products ``t1 t0^T - t0 t1^T``. With ``p = 4 / chi - |kb|^2``,
    ``r = 4 c / chi + |kb|^2`` and, for block ``a`` (``b`` the other edge),
    ``U`` (the Hessian being ``U + U^T``) is

    * ``(m / l_a) (p t_a - r t_b)`` times ``(((1 - c) t_a + 2 t_b) / l_a)`` (both 6-vectors, by blocks),
      ``m = -2 k / chi^2``,
    * ``-(k |kb|^2 / chi^2) v v^T`` with ``v = (w / l0, w / l1)``, ``w = t0 + t1``,
    * in the blocks ``aa``: ``-c_a (t_a ((p - |kb|^2 / 2) t_a - r t_b)^T + (2 / chi) t_b t_b^T)``
      and ``c_a (2 / chi - |kb|^2 / 2) I``, ``c_a = 2 k / (chi l_a^2)``,
    * in the block ``01``: ``alpha (t0 (r t0 + (|kb|^2 + 4 / chi) t1)^T + (r t1 - 4 t0 / chi) t1^T
      - (4 / chi) t1 t0^T - r I)``, ``alpha = 2 k / (chi l0 l1)``.
    """
    T, Tr, inv, c = acc.T, acc.T[::-1], acc.inv, acc.cos
    s2 = 2.0 * k
    ichi = 1.0 / (1.0 + c)
    u = 1.0 - c
    kk = 4.0 * u * ichi
    p = 4.0 * ichi - kk
    r = 4.0 * c * ichi + kk
    X, Y = acc.claim()
    X, Y = _view(X, (2, 3, -1)), _view(Y, (2, 3, -1))
    mi = (-s2 * ichi * ichi) * inv
    np.subtract((mi * p)[:, None] * T, (mi * r)[:, None] * Tr, out=X)
    np.add((u * inv)[:, None] * T, (2.0 * inv)[:, None] * Tr, out=Y)
    X, Y = acc.claim()
    np.multiply(T[0] + T[1], inv[:, None], out=_view(Y, (2, 3, -1)))
    np.multiply(Y, (-0.5 * s2) * kk * ichi * ichi, out=X)
    ca = (s2 * ichi) * inv * inv
    alpha = s2 * ichi * inv[0] * inv[1]
    R = acc.R
    R[0:6:5] -= (ca * (p - 0.5 * kk))[:, None] * T - (ca * r)[:, None] * Tr
    R[2:8:5] -= (2.0 * ichi * ca)[:, None] * Tr
    ar, a4 = alpha * r, 4.0 * alpha * ichi
    R[1] += ar * T[0] + (alpha * kk + a4) * T[1]
    R[4] += ar * T[1] - a4 * T[0]
    R[3] -= a4 * T[0]
    acc.diagonal[:2] += (2.0 * ichi - 0.5 * kk) * ca
    acc.diagonal[2] -= ar


# -- the reference twist over the edge vectors ----------------------------------------------


class TwistTerms(NamedTuple):
    """The reference-twist change and what its Hessian is built from (component-major arrays)."""

    beta: np.ndarray
    grad: np.ndarray  # (6, h) over the edge vectors
    grad_t: np.ndarray  # (6, h) over the tangents
    parts: tuple | None


def stored_twist_terms(s0, s1) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """What the second triangle of the reference twist takes from the stored tangents alone:
    ``s1 x s0``, ``s0 + s1`` (3, h) and ``s1 . s0`` (h,)."""
    return _cross(s1, s0), s0 + s1, _dot(s1, s0)


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
    _cross(t1, s0, out=gN1[0])
    _cross(s0, t0, out=gN1[1])
    gN2, gD2, s1s0 = stored_twist_terms(s0, s1) if stored is None else stored
    # N1 = s0 . (t0 x t1), D1 = 1 + t0 . t1 + s0 . (t0 + t1); N2 = s0 . (t1 x s1), D2 = 1 + (s0 + s1) . t1 + s1 . s0
    N1, N2 = _dot(t0, gN1[0]), _dot(t1, gN2)
    s0t1 = _dot(s0, t1)
    D1 = 1.0 + _dot(t0, t1) + _dot(s0, t0) + s0t1
    gD1 = s0 + T[::-1]
    R1 = N1 * N1 + D1 * D1
    G1 = D1 * gN1
    G1 -= N1 * gD1
    D2 = 1.0 + s0t1 + _dot(s1, t1) + s1s0
    R2 = N2 * N2 + D2 * D2
    G2 = D2 * gN2 - N2 * gD2
    beta = -2.0 * (np.arctan2(N1, D1) + np.arctan2(N2, D2))
    gt = (-2.0 / R1) * G1
    gt[1] -= (2.0 / R2) * G2
    gtt = _dot(gt, T)
    g = gt - gtt[:, None] * T
    g *= inv[:, None]
    parts = None
    if order == 2:
        parts = (N1, D1, R1, gN1, gD1, N2, D2, R2, G2, gN2, gD2, gtt)
    return TwistTerms(beta, _view(g, (6, -1)), _view(gt, (6, -1)), parts)


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
    b = gR1 - _dot(gR1, T)[:, None] * T
    b *= (2.0 * inv)[:, None]
    b = _view(b, (6, -1))
    X, Y = acc.claim()
    X[...] = g
    np.subtract(k * g, (0.5 * c / R1) * b, out=Y)
    X, Y = acc.claim()
    X[:3] = 0.0
    # P1 G2 / l1 and 2 P1 (N2 gN2 + D2 gD2) / l1
    np.multiply(G2 - _dot(G2, t1) * t1, inv[1], out=X[3:])
    np.multiply(b, -c / (R1 * R2), out=Y)
    gR2 = N2 * gN2
    gR2 += D2 * gD2
    gR2 -= _dot(gR2, t1) * t1
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
    R[0:6:5] -= sc[:, None] * (_view(terms.grad_t, (2, 3, -1)) - (1.5 * gtt)[:, None] * T)
    acc.diagonal[:2] -= 0.5 * sc * gtt
    # tau = theta1 - theta0 + m: its gradient over z is (grad beta, -1, 1)
    k2 = 2.0 * k
    kg = k2 * g
    theta = acc.theta
    theta[:, 0] -= kg
    theta[:, 1] += kg
    acc.theta2[0:3:2] += k2
    acc.theta2[1] -= k2


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


def _upper_pairs() -> np.ndarray:
    """The 66 entries on and above the diagonal of a stencil Hessian, block by block (see :meth:`HingeHessian.upper`)."""
    pairs = [(i, j) for i in range(3) for j in range(i, 3)]  # x0 x0
    pairs += [(i, 3 + j) for i in range(3) for j in range(3)]  # x0 x1
    pairs += [(i, 6 + j) for i in range(3) for j in range(3)]  # x0 x2
    pairs += [(3 + i, 3 + j) for i in range(3) for j in range(i, 3)]  # x1 x1
    pairs += [(3 + i, 6 + j) for i in range(3) for j in range(3)]  # x1 x2
    pairs += [(6 + i, 6 + j) for i in range(3) for j in range(i, 3)]  # x2 x2
    pairs += [(3 * n + i, 9 + j) for n in range(3) for i in range(3) for j in range(2)]  # x theta
    pairs += [(9, 9), (9, 10), (10, 10)]  # theta theta
    return np.array(pairs)


UPPER_PAIRS = _upper_pairs()
# flat indices into a Hessian over z (8, 8) and into a 3 x 3 block
_Z_TT = np.array([54, 55, 63])  # H_{theta theta}, upper
_BLOCK_UPPER = np.array([0, 1, 2, 4, 5, 8])
_BLOCK_UPPER_T = np.array([0, 3, 6, 4, 7, 8])


def stencil_pattern(stencil: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """COO pattern of the stencil Hessians in the order of a C-contiguous ``(11, 11, h)`` value array."""
    s = np.ascontiguousarray(stencil.T)  # (11, h)
    k, h = s.shape
    rows = np.broadcast_to(s[:, None, :], (k, k, h)).ravel()
    cols = np.broadcast_to(s[None, :, :], (k, k, h)).ravel()
    return rows.astype(np.int64), cols.astype(np.int64)


# -- the Hessian over the edge vectors as batched rank-one terms -------------------------------

#: shared slots of :class:`HingeHessian`: the left vector ``t0`` or ``t1`` in block 0 or 1 of ``z``
T0_0, T1_0, T1_1, T0_1 = range(4)


def _view(a: np.ndarray, shape: tuple) -> np.ndarray:
    """``a`` with another shape, as a view (never a copy: results are written to it)."""
    return np.reshape(a, shape, copy=False)


class HingeHessian:
    """The Hessian over ``z`` of a sum of hinge energies, collected term by term and carried to the stencil once.

    Over the edge vectors the Hessian is ``U + U^T``, ``U`` the product
    ``X^T Y`` of two stacks of 6-vectors per hinge (one batched product of
    small matrices for all rank-one terms of all hinges) plus multiples of the
    identity in the blocks ``00``, ``11`` and ``01`` (:attr:`diagonal`) and a
    cross-product matrix in the block ``01`` (:attr:`skew`). The first four
    slots have fixed left vectors, ``(t0, 0)``, ``(t1, 0)``, ``(0, t1)`` and
    ``(0, t0)`` (:data:`T0_0`, ...), and the effects add to their right
    vectors (:meth:`right`); each effect fills further slots of its own
    (:meth:`claim`). The second derivatives with the twist angles are
    collected as they are, :attr:`theta` (6, 2, h) and :attr:`theta2` (3, h)
    (the upper triangle), and Hessians over ``z`` given whole (8, 8, n) on
    some hinges are added at the end (:attr:`whole`: pairs of hinge indices,
    or None for all, and values). All arrays are component-major (hinge index
    last) but for the copies of the stacks that the batched product reads.
    """

    def __init__(self, h: int, slots: int):
        k = 4 + slots
        self.h = h
        self._XY = np.zeros((2, k, 6, h))
        self.X, self.Y = self._XY
        self._hinge_major = np.empty((h, 2, k, 6))  # the copy the product reads
        self.U = np.empty((6, 6, h))
        self.R = _view(self.Y[:4], (8, 3, h))  # right vectors of the shared slots by blocks: 2 slot + block
        self.T = np.empty((2, 3, h))
        self.inv = np.empty((2, h))
        self.cos = None
        self.diagonal = np.empty((3, h))
        self.skew = np.empty((3, h))
        self.theta = np.empty((6, 2, h))
        self.theta2 = np.empty((3, h))
        self.whole = []
        self._next = 4

    def start(self, t0: np.ndarray, t1: np.ndarray, l0: np.ndarray, l1: np.ndarray) -> None:
        """Begin a new sum at the tangents ``t0, t1`` (3, h) and lengths ``l0, l1`` (h,) of the edges.

        Sets :attr:`T` (2, 3, h), the tangents, :attr:`inv` (2, h), the inverse
        lengths, and :attr:`cos`, ``t0 . t1``, which the effects share.
        """
        T = self.T
        T[0] = t0
        T[1] = t1
        np.divide(1.0, l0, out=self.inv[0])
        np.divide(1.0, l1, out=self.inv[1])
        self.cos = _dot(t0, t1)
        X = self.X
        X[T0_0:T1_0 + 1, :3] = T
        X[T1_1:T0_1 + 1, 3:] = T[::-1]
        self.Y[:4] = 0.0
        self.diagonal.fill(0.0)
        self.skew.fill(0.0)
        self.theta.fill(0.0)
        self.theta2.fill(0.0)
        self.whole = []
        self._next = 4

    def claim(self) -> tuple[np.ndarray, np.ndarray]:
        """Left and right vectors (6, h) of a slot of the caller's own, to be written in full."""
        k = self._next
        self._next += 1
        return self.X[k], self.Y[k]

    def right(self, slot: int, block: int) -> np.ndarray:
        """Block ``block`` (3, h) of the right vector of the shared slot ``slot``."""
        return self.Y[slot, 3 * block:3 * block + 3]

    def _position(self) -> np.ndarray:
        """``U`` (6, 6, h), all terms summed."""
        U = self.U
        XY = self._hinge_major
        np.copyto(XY, self._XY.transpose(3, 0, 1, 2))
        np.matmul(XY[:, 0].transpose(0, 2, 1), XY[:, 1], out=U.transpose(2, 0, 1))
        flat = _view(U, (36, self.h))
        for block, first in enumerate((0, 21, 3)):
            flat[first:first + 15:7] += self.diagonal[block]
        s = self.skew
        flat[4] -= s[2]
        flat[5] += s[1]
        flat[9] += s[2]
        flat[11] -= s[0]
        flat[15] -= s[1]
        flat[16] += s[0]
        for sub, H in self.whole:
            sel = slice(None) if sub is None else sub
            U[:, :, sel] += 0.5 * H[:6, :6]
            self.theta[:, :, sel] += H[:6, 6:]
            self.theta2[:, sel] += _view(H, (64, -1))[_Z_TT]
        return U

    def full(self) -> np.ndarray:
        """The Hessian over ``z``, (8, 8, h)."""
        U = self._position()
        H = np.empty((8, 8, self.h))
        np.add(U, U.swapaxes(0, 1), out=H[:6, :6])
        H[:6, 6:] = self.theta
        H[6:, :6] = self.theta.swapaxes(0, 1)
        H[6, 6], H[6, 7], H[7, 7] = self.theta2
        H[7, 6] = H[6, 7]
        return H

    def upper(self, out: np.ndarray | None = None) -> np.ndarray:
        """The entries :data:`UPPER_PAIRS` of the stencil Hessian, (66, h), written to ``out`` if given.

        With the blocks ``A = H_{e0 e0}``, ``B = H_{e0 e1}``, ``C = H_{e1 e1}``,
        ``a = H_{e0 theta}``, ``c = H_{e1 theta}``: ``x0 x0: A``, ``x0 x1: B - A``,
        ``x0 x2: -B``, ``x1 x1: A - B - B^T + C = -(x0 x1) - (x1 x2)^T``,
        ``x1 x2: B - C``, ``x2 x2: C``, ``x0 theta: -a``, ``x1 theta: a - c``,
        ``x2 theta: c`` (``e^0 = x1 - x0``, ``e^1 = x2 - x1``); the diagonal
        node blocks by their upper triangles.
        """
        h = self.h
        U = self._position()
        out = np.empty((66, h)) if out is None else _view(out, (66, h))
        A = U[:3, :3] + U[:3, :3].swapaxes(0, 1)
        B = U[:3, 3:] + U[3:, :3].swapaxes(0, 1)
        C = U[3:, 3:] + U[3:, 3:].swapaxes(0, 1)
        np.take(_view(A, (9, h)), _BLOCK_UPPER, axis=0, out=out[0:6])
        x01, x12 = out[6:15], out[30:39]
        np.subtract(B, A, out=_view(x01, (3, 3, h)))
        np.negative(B, out=_view(out[15:24], (3, 3, h)))
        np.subtract(B, C, out=_view(x12, (3, 3, h)))
        x11 = out[24:30]
        np.take(x01, _BLOCK_UPPER, axis=0, out=x11)
        x11 += np.take(x12, _BLOCK_UPPER_T, axis=0)
        np.negative(x11, out=x11)
        np.take(_view(C, (9, h)), _BLOCK_UPPER, axis=0, out=out[39:45])
        a, c = self.theta[:3], self.theta[3:]
        np.negative(a, out=_view(out[45:51], (3, 2, h)))
        np.subtract(a, c, out=_view(out[51:57], (3, 2, h)))
        out[57:63] = _view(c, (6, h))
        out[63:66] = self.theta2
        return out


# -- common machinery of the hinge effects ------------------------------------------------


class HingeEffect(Effect):
    """Base of the effects defined on rod hinges (11-DOF stencils) with shared reference frames.

    The energy of hinge ``i`` is ``k_i f_i`` with ``k_i = stiffness_i / (2 dl_i)``.
    Subclasses implement ``_local(q, order)`` returning the energy per hinge
    (h,) and, for ``order >= 1``, its gradient (8, h) over
    ``z = (e0, e1, theta0, theta1)`` (component-major), and
    :meth:`add_hessian`, which adds the Hessian over ``z`` to a
    :class:`HingeHessian` (by default the Hessian (8, 8, h) of
    ``_local(q, 2)``). The Hessian values of effects on the same hinges are
    collected together and carried to the stencil once
    (:meth:`summed_hessian_upper_values`).

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
        self._upper_pattern = None
        self._scratch = {}  # HingeHessian arrays reused between evaluations, by number of slots
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
        return stencil_hessian(HingeEffect._hessian([self], q).full()).ravel()

    def hessian_upper_pattern(self):
        """The entries :data:`UPPER_PAIRS` of every hinge, entry-major ``(66, h)``."""
        if self._upper_pattern is None:
            rows = self._dofs_t[UPPER_PAIRS[:, 0]].ravel()
            cols = self._dofs_t[UPPER_PAIRS[:, 1]].ravel()
            mirrored = np.repeat(UPPER_PAIRS[:, 0] != UPPER_PAIRS[:, 1], self.stencil.shape[0])
            self._upper_pattern = (rows, cols, mirrored)
        return self._upper_pattern

    def hessian_upper_values(self, q, out=None):
        return HingeEffect._hessian([self], q).upper(out).ravel()

    @classmethod
    def summed_hessian_upper_values(cls, effects, q, out=None):
        """Bending and twisting of the same hinges: their terms collected in one :class:`HingeHessian`,
        carried to the stencil once."""
        first = effects[0]
        if not all(isinstance(e, HingeEffect) and e.frames is first.frames
                   and (e.stencil is first.stencil or np.array_equal(e.stencil, first.stencil)) for e in effects):
            return super().summed_hessian_upper_values(effects, q, out)
        return HingeEffect._hessian(effects, q).upper(out).ravel()

    #: slots of a :class:`HingeHessian` of the effect's own
    hessian_slots = 0

    def add_hessian(self, q: np.ndarray, acc: HingeHessian) -> None:
        """Add the Hessian over ``z`` at ``q`` to ``acc``; by default the whole one, from ``_local(q, 2)``."""
        acc.whole.append((None, self._local(q, 2)[2]))

    @staticmethod
    def _hessian(effects, q) -> HingeHessian:
        """The sum of the Hessians of hinge effects on the same hinges, collected (scratch arrays of the first)."""
        first = effects[0]
        t0, t1, l0, l1 = first.frames.hinge_tangents(q)
        key = sum(e.hessian_slots for e in effects)
        acc = first._scratch.get(key)
        if acc is None:
            acc = first._scratch[key] = HingeHessian(t0.shape[1], key)
        acc.start(t0, t1, l0, l1)
        for e in effects:
            e.add_hessian(q, acc)
        return acc

    def accept(self, q: np.ndarray) -> None:
        """Make ``q`` the stored reference state (time-parallel transport of the frames)."""
        self.frames.update(q)
