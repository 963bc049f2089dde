"""Stretching of discrete elastic rods (Eq. 1a of the gridshell paper).

``E_s = 1/2 sum_j EA (eps^j)^2 |e_bar^j|`` with ``eps^j = |e^j| / |e_bar^j| - 1``:
the same law as an elastic bar on every rod edge, so the element formulas are
those of :class:`~shellform.effects.axial.AxialBar`; this class names the
effect and its output for rods, and evaluates the Hessian values on
component-major arrays (edge index last, pattern entry-major ``(6, 6, m)``),
the layout of the rod hinge effects.
"""

from __future__ import annotations

import numpy as np

from .axial import AxialBar


class RodStretching(AxialBar):
    """Axial stretching of all rod edges at once.

    Parameters
    ----------
    n_dof : int
        Size of the global DOF vector.
    edges : array_like (m, 2)
        End nodes of every rod edge.
    EA : array_like (m,)
        Axial stiffness [N].
    rest_length : array_like (m,)
        Undeformed edge lengths ``|e_bar|`` [m].
    """

    name = "rod_stretch"
    member_kind = "rod"
    #: a rod network loads the compiled kernels for its hinges anyway
    compiled_from = 0

    def __init__(self, n_dof: int, connectivity, EA, rest_length):
        super().__init__(n_dof, connectivity, EA, rest_length)
        self._component_major()

    def _component_major(self) -> None:
        d = self._dofs_columns()  # (6, m)
        k, m = d.shape
        self._pattern = (np.broadcast_to(d[:, None, :], (k, k, m)).ravel(), np.broadcast_to(d[None, :, :], (k, k, m)).ravel())

    def on_members(self, members, node_index, n_dof):
        out = super().on_members(members, node_index, n_dof)
        out._component_major()
        return out

    def hessian_upper_pattern(self):
        """The bar's upper pattern (:meth:`AxialBar.hessian_upper_pattern`), with or without numba: the rod
        hinges give theirs, and the stretching's values go with them."""
        return self._upper_pattern()

    def hessian_entries(self, members):
        """Indices into :meth:`hessian_pattern` of the entries of ``members`` (36 each, in block order)."""
        m = len(self.conn)
        return (np.arange(36)[None, :] * m + np.asarray(members, dtype=np.int64)[:, None]).ravel()

    def hessian_values(self, q):
        """``[[K, -K], [-K, K]]`` with ``K = (EA / L - N / l) n n^T + (N / l) I`` (see :mod:`~shellform.effects.axial`)."""
        x = q[self._dofs_columns()]
        d = x[3:] - x[:3]
        length = np.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
        N, k = self._force(length)
        s = N / length
        n = d / length
        H = np.empty((6, 6, length.size))
        K = H[:3, :3]
        np.multiply(((k - s) * n)[:, None], n[None], out=K)
        for i in range(3):
            K[i, i] += s
        np.negative(K, out=H[:3, 3:])
        H[3:, :3] = H[:3, 3:]
        H[3:, 3:] = K
        return H.ravel()
