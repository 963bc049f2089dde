"""Rotational springs at rod crossings: the scissor stiffness of a gridshell's joints.

Where two rods cross, a shared node (or a penalty joint) ties their positions
but lets them turn against each other freely, like the bolted scissor joints
of a gridshell while it is erected. A joint that is tightened or braced
resists that turn. This effect gives each crossing the energy

    E = 1/2 k (phi - phi_0)^2,

``phi`` the angle between the two rods at the crossing, each rod's direction
there taken as the chord ``u = x_b - x_a`` between two of its nodes (its
neighbours on either side of the crossing, or the crossing and its one
neighbour at a rod's end), ``phi_0`` that angle in the stress-free state and
``k`` the joint's rotational stiffness [N m/rad].

With ``s = |u x v|`` and ``c = u . v`` of the two chords,
``phi = atan2(s, c)``; its gradient and Hessian over ``(u, v)`` follow from
those of ``s`` and ``c`` in closed form (``c`` is bilinear, ``s`` the norm of
the bilinear ``w = u x v``), and the constant map from the four chord-end
nodes to ``(u, v)`` carries them to the node DOFs. Vectorised over crossings.
"""

from __future__ import annotations

import numpy as np

from ..errors import ModelError
from ..geometry.vectors import cross
from .base import Effect, element_pattern, scatter
from .rod_kinematics import skew

#: how the 12 node DOFs (a_u, b_u, a_v, b_v) of a crossing make the chords (u, v): u = x_b_u - x_a_u, ...
_MAP = np.kron(np.array([[-1.0, 1.0, 0.0, 0.0], [0.0, 0.0, -1.0, 1.0]]), np.eye(3))


def _chords(q: np.ndarray, ends: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    x = q[: 3 * (int(ends.max()) + 1)].reshape(-1, 3) if ends.size else np.zeros((0, 3))
    return x[ends[:, 1]] - x[ends[:, 0]], x[ends[:, 3]] - x[ends[:, 2]]


def crossing_angle(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """The angle between the chords of every crossing, in [0, pi]."""
    return np.arctan2(np.linalg.norm(cross(u, v), axis=1), np.einsum("ij,ij->i", u, v))


def angle_derivatives(u: np.ndarray, v: np.ndarray, hessian: bool = True):
    """``phi = atan2(|u x v|, u . v)`` with its gradient (n, 6) and Hessian (n, 6, 6) over ``(u, v)``."""
    n = len(u)
    w = cross(u, v)
    s = np.linalg.norm(w, axis=1)
    c = np.einsum("ij,ij->i", u, v)
    if np.any(s <= 1e-12 * np.linalg.norm(u, axis=1) * np.linalg.norm(v, axis=1)):
        k = int(np.argmin(s))
        raise ModelError(f"joint rotation: the rods of crossing {k} are parallel there; the angle between them "
                         "has no direction to turn in")
    wh = w / s[:, None]
    J = np.concatenate([-skew(v), skew(u)], axis=2)  # d w / d(u, v), (n, 3, 6)
    gs = np.einsum("nk,nka->na", wh, J)
    gc = np.concatenate([v, u], axis=1)
    R = s * s + c * c
    g = (c[:, None] * gs - s[:, None] * gc) / R[:, None]
    phi = np.arctan2(s, c)
    if not hessian:
        return phi, g, None
    # d2 s: J^T (I - wh wh^T) J / s plus wh . d2 w, the bilinear part: d2 w_k / du_i dv_j = eps_kij
    P = np.eye(3) - wh[:, :, None] * wh[:, None, :]
    Hs = np.einsum("nka,nkl,nlb->nab", J, P, J) / s[:, None, None]
    W = skew(wh)  # W_ij = -eps_ijk wh_k, so sum_k wh_k eps_kij = -W_ij
    Hs[:, :3, 3:] -= W
    Hs[:, 3:, :3] += W  # (-W)^T = W
    Hc = np.zeros((n, 6, 6))
    Hc[:, :3, 3:] = np.eye(3)
    Hc[:, 3:, :3] = np.eye(3)
    G = c[:, None] * gs - s[:, None] * gc
    dG = (gc[:, :, None] * gs[:, None, :] + c[:, None, None] * Hs
          - gs[:, :, None] * gc[:, None, :] - s[:, None, None] * Hc)
    dR = 2.0 * (s[:, None] * gs + c[:, None] * gc)
    H = dG / R[:, None, None] - G[:, :, None] * dR[:, None, :] / (R * R)[:, None, None]
    return phi, g, 0.5 * (H + np.swapaxes(H, 1, 2))


class JointRotation(Effect):
    """Rotational springs between the two rods of every crossing.

    Parameters
    ----------
    n_dof : int
    ends : array_like (k, 4)
        Per crossing, the nodes ``(a_u, b_u, a_v, b_v)``: the chord ``a_u -> b_u``
        of one rod and ``a_v -> b_v`` of the other.
    stiffness : float or array_like (k,)
        Rotational stiffness ``k`` [N m/rad].
    q0 : ndarray
        The stress-free state (gives ``phi_0``).
    """

    name = "joint_rotation"

    def __init__(self, n_dof: int, ends, stiffness, q0: np.ndarray):
        super().__init__(n_dof)
        self.ends = np.asarray(ends, dtype=np.int64).reshape(-1, 4)
        self.k = np.broadcast_to(np.asarray(stiffness, dtype=float), (len(self.ends),)).copy()
        if np.any(~np.isfinite(self.k) | (self.k < 0)):
            raise ModelError("joint rotation: the rotational stiffness must be a finite number >= 0")
        self.dofs = (3 * self.ends[:, :, None] + np.arange(3)).reshape(-1, 12)
        self._pattern = element_pattern(self.dofs)
        self.phi0 = crossing_angle(*_chords(np.asarray(q0, dtype=float), self.ends))

    def angle(self, q: np.ndarray) -> np.ndarray:
        """The angle between the rods of every crossing [rad]."""
        return crossing_angle(*_chords(q, self.ends))

    def energy(self, q):
        d = self.angle(q) - self.phi0
        return 0.5 * float(np.sum(self.k * d * d))

    def _node_forces(self, q):
        phi, g, _ = angle_derivatives(*_chords(q, self.ends), hessian=False)
        return (self.k * (phi - self.phi0))[:, None] * (g @ _MAP)

    def gradient(self, q):
        return scatter(self.n_dof, self.dofs, self._node_forces(q))

    def force_magnitudes(self, q):
        return scatter(self.n_dof, self.dofs, np.abs(self._node_forces(q)))

    def hessian_pattern(self):
        return self._pattern

    def hessian_values(self, q):
        phi, g, H = angle_derivatives(*_chords(q, self.ends))
        k, d = self.k[:, None, None], (phi - self.phi0)[:, None, None]
        local = k * (g[:, :, None] * g[:, None, :] + d * H)
        return np.einsum("ai,nab,bj->nij", _MAP, local, _MAP).ravel()

    def member_results(self, q):
        turn = self.angle(q) - self.phi0
        return {"turn": turn, "moment": self.k * turn}
