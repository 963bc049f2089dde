"""The 11-DOF stencil of a rod hinge: derivatives carried from the edge vectors to the stencil, its Hessian
pattern and upper triangle, and the collector of the hinge Hessians' terms.

A hinge's derivatives are written over ``z = (e^0, e^1, theta^0, theta^1)``; ``e^0 = x_1 - x_0`` and
``e^1 = x_2 - x_1`` carry them to the stencil ``(x_0, x_1, x_2, theta^0, theta^1)`` by differences of node
blocks (:func:`stencil_gradient`, :func:`stencil_hessian`). The System's tangents take the upper triangle of
each stencil Hessian (:data:`UPPER_PAIRS`), which :class:`HingeHessian` writes straight from the sum of the
terms of every effect on the same hinges. Component-major arrays, the hinge index last (see
:mod:`.rod_hinge`).
"""

from __future__ import annotations

import numpy as np

from .rod_vectors import inner, view


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
    """The 66 entries on and above the diagonal of a stencil Hessian, block by block
    (see :meth:`HingeHessian.upper`)."""
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


def stencil_upper(Hz: np.ndarray) -> np.ndarray:
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
