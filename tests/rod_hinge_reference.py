"""The layered dense formulation of the rod hinge derivatives, kept as an independent reference.

The curvature binormal and material-frame terms (layer 1) are the effects' own, which finite
differences check; the reference twist's derivatives and the composition are this module's.

Derivatives over ``(t0, t1, theta0, theta1)`` as dense (h, 8) and (h, 8, 8)
arrays, composed with the normalisation ``t = e / |e|`` and with the constant
0/+-1 map from the stencil DOFs to the edge vectors by dense products. Slow
but straightforward; the effects' own closed-form stencil derivatives are
compared with it entry by entry.
"""

from __future__ import annotations


import numpy as np

from shellform.effects.rod_material_frame import (  # shared: finite differences check it
    BinormalJacobian,
    curvature_binormal_jacobian,
    hessian_of_projected_binormal,
    material_curvature_term,
)
from shellform.effects.rod_kinematics import dot, skew

_I3 = np.eye(3)


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


# -- layers 2 and 3: normalisation and the map to the stencil, as dense products ---------


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
