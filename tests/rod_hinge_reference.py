"""The layered dense formulation of the rod hinge derivatives, kept as an independent reference.

Derivatives over ``(t0, t1, theta0, theta1)`` as dense (h, 8) and (h, 8, 8)
arrays, composed with the normalisation ``t = e / |e|`` and with the constant
0/+-1 map from the stencil DOFs to the edge vectors by dense products. Slow
but straightforward; the effects' own closed-form stencil derivatives are
compared with it entry by entry.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from shellform.effects.rod_kinematics import dot, skew

_I3 = np.eye(3)


# -- layer 1: curvature binormal ------------------------------------------------------


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


# -- layer 1: reference twist -------------------------------------------------------------


def _atan2_derivatives(N, D, gN, gD, HN, HD, hessian=True):
    """Value, gradient and (if asked) Hessian of ``2 atan2(N, D)``; ``HN``/``HD`` None mean zero."""
    R = N * N + D * D
    G = D[:, None] * gN - N[:, None] * gD
    g = 2.0 * G / R[:, None]
    if not hessian:
        return 2.0 * np.arctan2(N, D), g, None
    H = gN[:, :, None] * gD[:, None, :] - gD[:, :, None] * gN[:, None, :]
    if HN is not None:
        H += D[:, None, None] * HN - N[:, None, None] * HD
    H /= R[:, None, None]
    gR = 2.0 * (N[:, None] * gN + D[:, None] * gD)
    H -= G[:, :, None] * gR[:, None, :] / (R * R)[:, None, None]
    H = H + np.swapaxes(H, 1, 2)  # 2 * symmetric part
    return 2.0 * np.arctan2(N, D), g, H


def reference_twist_change(t0, t1, s0, s1, hessian=True):
    """Change of the reference twist from the stored state, with derivatives over ``(t0, t1)``.

    ``beta = -Omega(s0, t0, t1) - Omega(s0, t1, s1)`` (see
    :mod:`shellform.effects.rod_kinematics`), so that ``m(q) = m_stored + beta``.

    Returns
    -------
    beta : ndarray (n,)
    grad : ndarray (n, 6)
    hess : ndarray (n, 6, 6), or None when ``hessian`` is False
    """
    n = len(t0)
    # triangle (s0, t0, t1)
    N1 = dot(s0, np.cross(t0, t1))
    D1 = 1.0 + dot(s0, t0) + dot(t0, t1) + dot(t1, s0)
    gN1 = np.concatenate([np.cross(t1, s0), np.cross(s0, t0)], axis=1)
    gD1 = np.concatenate([s0 + t1, t0 + s0], axis=1)
    HN1 = HD1 = None
    if hessian:
        HN1 = np.zeros((n, 6, 6))
        S0 = skew(s0)
        HN1[:, :3, 3:] = -S0
        HN1[:, 3:, :3] = S0
        HD1 = np.zeros((n, 6, 6))
        HD1[:, :3, 3:] = _I3
        HD1[:, 3:, :3] = _I3
    w1, g1, H1 = _atan2_derivatives(N1, D1, gN1, gD1, HN1, HD1, hessian)
    # triangle (s0, t1, s1): numerator and denominator linear in t1 alone
    N2 = dot(s0, np.cross(t1, s1))
    D2 = 1.0 + dot(s0, t1) + dot(t1, s1) + dot(s1, s0)
    w2, g2, H2 = _atan2_derivatives(N2, D2, np.cross(s1, s0), s0 + s1, None, None, hessian)
    g = -g1
    g[:, 3:] -= g2
    if not hessian:
        return -(w1 + w2), g, None
    H = -H1
    H[:, 3:, 3:] -= H2
    return -(w1 + w2), g, H


# -- layer 1: material-frame term of the bending energy -----------------------------------


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


# -- layers 2 and 3: from tangents to stencil DOFs ------------------------------------


def _stencil_map() -> np.ndarray:
    """Constant map from stencil DOFs (x0, x1, x2, theta0, theta1) to (e0, e1, theta0, theta1)."""
    B = np.zeros((8, 11))
    B[0:3, 0:3] = -_I3
    B[0:3, 3:6] = _I3
    B[3:6, 3:6] = -_I3
    B[3:6, 6:9] = _I3
    B[6, 9] = 1.0
    B[7, 10] = 1.0
    return B


STENCIL_MAP = _stencil_map()


def to_stencil(t0, t1, l0, l1, g, H=None):
    """Transform gradient (n, 8) and Hessian (n, 8, 8) over ``(t0, t1, theta0, theta1)``
    to the 11 stencil DOFs ``(x0, x1, x2, theta0, theta1)``.

    With ``t = e / l`` and ``P = I - t t^T``: ``dF/de = P g_t / l`` and
    ``d2F/de2 = (P/l) H_tt (P/l) - (t g^T + g t^T + (g.t)(I - 3 t t^T)) / l^2``.
    """
    n = len(t0)
    Pt = np.empty((n, 8, 8))
    Pt[:] = 0.0
    for k, (t, l) in enumerate(((t0, l0), (t1, l1))):
        sl = slice(3 * k, 3 * k + 3)
        Pt[:, sl, sl] = (_I3 - t[:, :, None] * t[:, None, :]) / l[:, None, None]
    Pt[:, 6, 6] = 1.0
    Pt[:, 7, 7] = 1.0
    gz = np.einsum("nab,nb->na", Pt, g)
    g11 = gz @ STENCIL_MAP
    if H is None:
        return g11, None
    Hz = Pt @ H @ Pt
    for k, (t, l) in enumerate(((t0, l0), (t1, l1))):
        sl = slice(3 * k, 3 * k + 3)
        gt = g[:, sl]
        gdt = dot(gt, t)
        S = t[:, :, None] * gt[:, None, :]
        S = S + np.swapaxes(S, 1, 2)
        S += gdt[:, None, None] * (_I3 - 3.0 * t[:, :, None] * t[:, None, :])
        Hz[:, sl, sl] -= S / (l * l)[:, None, None]
    H11 = STENCIL_MAP.T @ Hz @ STENCIL_MAP
    return g11, H11


# -- the effects' derivatives on the stencil, by the layered formulation -------------------

_COMPONENT = (np.array([1.0, 0.0]), np.array([0.0, 1.0]))


def _geometry(effect, q):
    t, l = effect.frames.tangents(q)
    h0, h1 = effect.hinge_edges[:, 0], effect.hinge_edges[:, 1]
    theta = q[effect.stencil[:, 9:]]
    return t[h0], t[h1], l[h0], l[h1], theta


def _stored_frame(frames, edges):
    u = frames.director[edges]
    s = frames.tangent[edges]
    return np.stack([u, np.cross(s, u), s], axis=2)


def bending_local(effect, q):
    """Energy, gradient (h, 8) and Hessian (h, 8, 8) over ``(t0, t1, theta0, theta1)`` of :class:`RodBending`."""
    t0, t1, l0, l1, theta = _geometry(effect, q)
    c, a = effect.curved, effect.aniso
    kb, chi, J = curvature_binormal_jacobian(t0, t1)
    n = len(t0)
    e = dot(kb, kb) + effect._const
    g = np.zeros((n, 8))
    g[:, :6] = 2.0 * np.einsum("nk,nka->na", kb, J)
    H = np.zeros((n, 8, 8))
    H[:, :6, :6] = 2.0 * np.einsum("nka,nkb->nab", J, J) + 2.0 * hessian_of_projected_binormal(t0, t1, kb, chi, J, kb)
    for j in (0, 1):
        if c.size:
            f, gj, Hj = material_curvature_term(
                t0[c], t1[c], BinormalJacobian(kb[c], chi[c], J[c]), j,
                _stored_frame(effect.frames, effect.hinge_edges[c, j]), effect._w_bar[c, j], theta[c, j])
            e[c] -= f
            g[c] -= gj
            H[c] -= Hj
        if a.size:
            frame = _stored_frame(effect.frames, effect.hinge_edges[a, j])
            for sign, unit in zip((1.0, -1.0), _COMPONENT):
                f, gf, Hf = material_curvature_term(
                    t0[a], t1[a], BinormalJacobian(kb[a], chi[a], J[a]), j, frame,
                    np.broadcast_to(unit, (a.size, 2)), theta[a, j])
                s = sign * effect._split
                e[a] += s * f * f
                g[a] += (2.0 * s * f)[:, None] * gf
                H[a] += (2.0 * s)[:, None, None] * (gf[:, :, None] * gf[:, None, :] + f[:, None, None] * Hf)
    k = effect.k
    return k * e, g * k[:, None], H * k[:, None, None]


def twisting_local(effect, q):
    """Energy, gradient and Hessian over ``(t0, t1, theta0, theta1)`` of :class:`RodTwisting`."""
    t0, t1, _, _, theta = _geometry(effect, q)
    h0, h1 = effect.hinge_edges[:, 0], effect.hinge_edges[:, 1]
    beta, gb, Hb = reference_twist_change(t0, t1, effect.frames.tangent[h0], effect.frames.tangent[h1])
    dtau = theta[:, 1] - theta[:, 0] + effect.frames.twist + beta - effect.tau_bar
    n = len(t0)
    gtau = np.zeros((n, 8))
    gtau[:, :6] = gb
    gtau[:, 6] = -1.0
    gtau[:, 7] = 1.0
    k2 = 2.0 * effect.k
    g = (k2 * dtau)[:, None] * gtau
    H = k2[:, None, None] * gtau[:, :, None] * gtau[:, None, :]
    H[:, :6, :6] += (k2 * dtau)[:, None, None] * Hb
    return effect.k * dtau**2, g, H


def stencil_derivatives(effect, q):
    """Energy per hinge, gradient (h, 11) and Hessian (h, 11, 11) on the stencil DOFs, by the layered route."""
    local = bending_local if effect.name == "rod_bend" else twisting_local
    e, g, H = local(effect, q)
    t0, t1, l0, l1, _ = _geometry(effect, q)
    g11, H11 = to_stencil(t0, t1, l0, l1, g, H)
    return e, g11, H11
