"""The material-frame terms of curved and anisotropic rod hinges, with their derivatives over the tangents.

A hinge's bending energy sees its edges' material frames where the rod is
naturally curved (``omega_bar . omega^j``) or its section anisotropic: these
terms are written over ``y = (t0, t1, theta0, theta1)`` (8 variables) as dense
per-hinge gradients and Hessians, every quantity a rational function of the
tangents (the curvature binormal, the directors parallel-transported from the
stored frames) or a sine or cosine of the angles; :mod:`.rod_hinge` carries
them through the normalisation of the tangents to the stencil. All functions
are vectorised over hinges (leading axis ``n``).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..geometry.vectors import cross
from .rod_kinematics import dot, skew

_I3 = np.eye(3)


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
    kb = 2.0 * cross(t0, t1) / chi[:, None]
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
