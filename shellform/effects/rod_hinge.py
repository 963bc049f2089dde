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
(:data:`UPPER_PAIRS`) for the System's tangents. Where numba is installed the
System's tangents take the same upper values from a kernel compiled per
hinge (:mod:`.rod_compiled`, :meth:`HingeEffect.upper_scatter`), added
straight into the tangent's data; the collection stays the reference and the
form without numba. The energies and gradients of the same terms are compiled
as well (:meth:`HingeEffect._compiled_forces`), with the NumPy form
(``_local``) their reference and the form without numba.

Array layout: the closed-form functions work on *component-major* arrays with
the hinge index last (vectors ``(3, h)``, Hessians ``(8, 8, h)``), so that every
arithmetic operation runs over all hinges on contiguous memory; the effects'
Hessian patterns follow the same order (entry-major, ``(11, 11, h)`` and
``(66, h)``). The layered dense form of the same derivatives (over the
tangents, then through dense 0/+-1 maps) serves as the reference in the tests.

The reference twist's derivatives are in :mod:`.rod_reference_twist`, the
material-frame terms of curved and anisotropic hinges in
:mod:`.rod_material_frame`, the component-major algebra in :mod:`.rod_vectors`.

Conventions (Bergou et al. 2008): curvature binormal
``kb = 2 t^0 x t^1 / (1 + t^0 . t^1)``; material curvature of edge ``j`` at the
hinge ``omega^j = (kb . m2^j, -kb . m1^j)``; twist
``tau = theta^1 - theta^0 + m`` with ``m`` the reference twist
(:mod:`shellform.effects.rod_kinematics`).
"""

from __future__ import annotations

import numpy as np

from .base import Effect
from .rod_vectors import cross, inner, outer, project, subtract_curvature, view


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
    chi = 1.0 + inner(t0, t1)
    ichi = 1.0 / chi
    kb = (2.0 * ichi) * cross(t0, t1)
    kk = inner(kb, kb)
    if order == 0:
        return (kk,)
    s2 = 2.0 if scale is None else 2.0 * scale
    w = t0 + t1
    kw = kk * w
    gh = np.empty((6,) + kk.shape)  # K^T kb
    np.multiply(2.0 * cross(t1, kb) - kw, s2 * ichi / l0, out=gh[:3])
    np.multiply(2.0 * cross(kb, t0) - kw, s2 * ichi / l1, out=gh[3:])
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
    X, Y = view(X, (2, 3, -1)), view(Y, (2, 3, -1))
    mi = (-s2 * ichi * ichi) * inv
    np.subtract((mi * p)[:, None] * T, (mi * r)[:, None] * Tr, out=X)
    np.add((u * inv)[:, None] * T, (2.0 * inv)[:, None] * Tr, out=Y)
    X, Y = acc.claim()
    np.multiply(T[0] + T[1], inv[:, None], out=view(Y, (2, 3, -1)))
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


# -- from the edge vectors to the stencil -----------------------------------------------------


def project_to_edges(t0, t1, l0, l1, g, H=None):
    """Carry a gradient (8, h) and Hessian (8, 8, h) over ``(t0, t1, theta0, theta1)`` to ``z``.

    The general form of the chain rule through the normalisation, for terms
    given over the tangents (the material-frame terms of curved and
    anisotropic hinges).
    """
    i0, i1 = 1.0 / l0, 1.0 / l1
    gz = g.copy()
    gz[:3] = project(g[:3], t0, i0)
    gz[3:6] = project(g[3:6], t1, i1)
    if H is None:
        return gz, None
    Hz = H.copy()
    for a, t in enumerate((t0, t1)):
        s = slice(3 * a, 3 * a + 3)
        Hz[:, s] -= outer((Hz[:, s] * t).sum(axis=1), t)
        Hz[s] -= outer(t, (Hz[s] * t[:, None]).sum(axis=0))
    scale = np.ones_like(g)
    scale[:3] = i0
    scale[3:6] = i1
    Hz *= outer(scale, scale)
    for a, (t, ia) in enumerate(((t0, i0), (t1, i1))):
        s = slice(3 * a, 3 * a + 3)
        W = np.zeros((3, 3) + i0.shape)
        subtract_curvature(W, t, g[s], -ia * ia)
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
_STENCIL_UPPER = UPPER_PAIRS[:, 0] * 11 + UPPER_PAIRS[:, 1]  # UPPER_PAIRS as flat indices into (11, 11)


def _stencil_upper(Hz: np.ndarray) -> np.ndarray:
    """The entries :data:`UPPER_PAIRS` (66, n) of the stencil Hessians from symmetric ones over ``z`` (8, 8, n)."""
    return view(stencil_hessian(Hz), (121, -1))[_STENCIL_UPPER]


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
        self.R = view(self.Y[:4], (8, 3, h))  # right vectors of the shared slots by blocks: 2 slot + block
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
        self.cos = inner(t0, t1)
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
        flat = view(U, (36, self.h))
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
            self.theta2[:, sel] += view(H, (64, -1))[_Z_TT]
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
        out = np.empty((66, h)) if out is None else view(out, (66, h))
        A = U[:3, :3] + U[:3, :3].swapaxes(0, 1)
        B = U[:3, 3:] + U[3:, :3].swapaxes(0, 1)
        C = U[3:, 3:] + U[3:, 3:].swapaxes(0, 1)
        np.take(view(A, (9, h)), _BLOCK_UPPER, axis=0, out=out[0:6])
        x01, x12 = out[6:15], out[30:39]
        np.subtract(B, A, out=view(x01, (3, 3, h)))
        np.negative(B, out=view(out[15:24], (3, 3, h)))
        np.subtract(B, C, out=view(x12, (3, 3, h)))
        x11 = out[24:30]
        np.take(x01, _BLOCK_UPPER, axis=0, out=x11)
        x11 += np.take(x12, _BLOCK_UPPER_T, axis=0)
        np.negative(x11, out=x11)
        np.take(view(C, (9, h)), _BLOCK_UPPER, axis=0, out=out[39:45])
        a, c = self.theta[:3], self.theta[3:]
        np.negative(a, out=view(out[45:51], (3, 2, h)))
        np.subtract(a, c, out=view(out[51:57], (3, 2, h)))
        out[57:63] = view(c, (6, h))
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
        self.stencil = np.ascontiguousarray(stencil, dtype=np.int64)  # read by the compiled kernels hinge by hinge
        self.hinge_edges = frames.hinges
        self._dofs_t = np.ascontiguousarray(self.stencil.T)
        self._pattern = stencil_pattern(self.stencil)
        self._upper_pattern = None
        self._scratch = {}  # HingeHessian arrays reused between evaluations, by number of slots
        self._last_forces = None  # (q, the terms' arrays, energies) of the last compiled gradient
        self.voronoi = np.asarray(voronoi, dtype=float)
        self.k = np.asarray(stiffness, dtype=float) / (2.0 * self.voronoi)

    def _geometry(self, q):
        """Tangents (3, h) and lengths (h,) of both edges of every hinge, and the twist angles (2, h)."""
        t0, t1, l0, l1 = self.frames.hinge_tangents(q)
        return t0, t1, l0, l1, q[self._dofs_t[9:]]

    def energy(self, q):
        e = self._compiled_forces(q)
        return float(np.sum(self._local(q, 0)[0] if e is None else e))

    def _stencil_forces(self, q):
        """Gradient of every hinge's energy on its 11 stencil DOFs, shape (11, h)."""
        return stencil_gradient(self._local(q, 1)[1])

    def gradient(self, q):
        g = np.zeros(self.n_dof)
        if self._compiled_forces(q, g) is None:
            return np.bincount(self._dofs_t.ravel(), weights=self._stencil_forces(q).ravel(), minlength=self.n_dof)
        return g

    def force_magnitudes(self, q):
        g = np.zeros(self.n_dof)
        if self._compiled_forces(q, g, absolute=True) is None:
            return np.bincount(self._dofs_t.ravel(), weights=np.abs(self._stencil_forces(q)).ravel(),
                               minlength=self.n_dof)
        return g

    def _compiled_forces(self, q, grad=None, absolute=False) -> np.ndarray | None:
        """The energy of every hinge (h,), its gradient added to ``grad`` if given (the magnitudes of each hinge's
        forces where ``absolute``), from the kernel compiled per hinge (:func:`.rod_compiled.hinge_forces`: the
        kinematics of a hinge once, straight from ``q``, and no arrays between the steps); None where numba is not
        installed or the effect has no :meth:`kernel_terms`: the NumPy form (:meth:`_local`)."""
        from . import rod_compiled as compiled

        terms = self.kernel_terms(q) if compiled.available else None
        if terms is None:
            return None
        # a solver asks for the energy where it has just asked for the gradient (a line search's trial
        # point): the energies of that pass serve, while the terms' arrays are the same objects (the
        # effects and their frames replace them, never change them in place) and q is equal
        key = tuple(a for t in terms.values() for a in (t if isinstance(t, tuple) else (t,)))
        last = getattr(self, "_last_forces", None)
        if grad is None and last is not None and len(last[1]) == len(key) \
                and all(a is b for a, b in zip(last[1], key)) and np.array_equal(last[0], q):
            return last[2].copy()
        e = compiled.hinge_forces(q, self.stencil, terms.get("bending"), terms.get("twisting"), grad, absolute)
        if grad is not None:
            self._last_forces = (np.array(q, dtype=float), key, e.copy())
        return e

    def kernel_terms(self, q: np.ndarray) -> dict | None:
        """The terms of :meth:`compiled_terms` but ``"whole"``: what the compiled kernels evaluate for this effect
        (None, the default: the NumPy form)."""
        return None

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
        return HingeEffect._upper_values([self], q, out)

    @classmethod
    def summed_hessian_upper_values(cls, effects, q, out=None):
        """Bending and twisting of the same hinges: their terms evaluated together and carried to the stencil
        once (:meth:`_upper_values`)."""
        first = effects[0]
        if not all(isinstance(e, HingeEffect) and e.frames is first.frames
                   and (e.stencil is first.stencil or np.array_equal(e.stencil, first.stencil)) for e in effects):
            return super().summed_hessian_upper_values(effects, q, out)
        return HingeEffect._upper_values(effects, q, out)

    @staticmethod
    def _upper_values(effects, q, out=None) -> np.ndarray:
        """The summed upper stencil Hessians of effects on the same hinges, flat ``(66 h,)``.

        Compiled per hinge (:mod:`.rod_compiled`) when every effect
        gives its :meth:`compiled_terms` and numba is installed, collected in
        a :class:`HingeHessian` otherwise.
        """
        # imported here: numba's import alone takes 0.1-0.3 s, which models without rods never need
        from . import rod_compiled as compiled

        terms = HingeEffect._compiled_terms(effects, q) if compiled.available else None
        if terms is None:
            return HingeEffect._hessian(effects, q).upper(out).ravel()
        h = effects[0].stencil.shape[0]
        values = np.empty((66, h)) if out is None else view(out, (66, h))
        compiled.upper_values(q, effects[0].stencil, terms.get("bending"), terms.get("twisting"), values)
        for sub, H in terms["whole"]:
            values[:, sub] += _stencil_upper(H)
        return values.ravel()

    @classmethod
    def upper_scatter(cls, effects, first: np.ndarray, second: np.ndarray):
        """A function ``add(effects, q, data)`` that adds the summed upper stencil Hessians of ``effects`` (on
        the same hinges) to the data of a sparse matrix, or None where it cannot (numba not installed, an
        effect without :meth:`compiled_terms`).

        ``first`` and ``second`` give, for every value of
        :meth:`hessian_upper_pattern`, the slots in ``data`` of its entry and
        of its mirror (the last slot where there is none). The function takes
        the effects when it is called: a copy of the System with copies of its
        effects (another stiffness, say) shares the slots.
        """
        from . import rod_compiled as compiled

        if not compiled.available or any(type(e).compiled_terms is HingeEffect.compiled_terms
                                         or e.frames is not effects[0].frames for e in effects):
            return None
        # hinge-major: the kernel adds the values of one hinge after the other
        first, second = (compiled.element_major(a, 66) for a in (first, second))

        def add(effects, q: np.ndarray, data: np.ndarray) -> None:
            terms = HingeEffect._compiled_terms(effects, q)
            compiled.add_upper_values(q, effects[0].stencil, terms.get("bending"), terms.get("twisting"), data,
                                      first, second)
            for sub, H in terms["whole"]:
                compiled.scatter(data, first, second, sub, _stencil_upper(H))

        return add

    @staticmethod
    def _compiled_terms(effects, q) -> dict | None:
        """The :meth:`compiled_terms` of ``effects`` merged, or None if one has none or two give the same term."""
        terms = {"whole": []}
        for e in effects:
            own = e.compiled_terms(q)
            if own is None or set(own) & set(terms) - {"whole"}:
                return None
            terms.update(own, whole=terms["whole"] + own.get("whole", []))
        return terms

    def compiled_terms(self, q: np.ndarray) -> dict | None:
        """What the compiled hinge kernel takes from this effect at ``q``, or None (the default): the NumPy form.

        Keys: ``"bending"``, the stiffness ``k`` (h,) of an isotropic
        ``k |kb|^2``; ``"twisting"``, a
        :class:`~shellform.effects.rod_reference_twist.TwistInputs`;
        ``"whole"``, a list of pairs of hinge indices and Hessians over ``z``
        (8, 8, n) added as they are.
        """
        return None

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
