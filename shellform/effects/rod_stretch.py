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


#: the upper triangle of a 3 x 3 block, as flat indices
_UPPER = np.array([0, 1, 2, 4, 5, 8])


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

    def __init__(self, n_dof: int, connectivity, EA, rest_length):
        super().__init__(n_dof, connectivity, EA, rest_length)
        self._component_major()

    def _component_major(self) -> None:
        self._upper_pattern = None
        self._dofs_t = np.ascontiguousarray(self.dofs.T)  # (6, m)
        k, m = self._dofs_t.shape
        self._pattern = (np.broadcast_to(self._dofs_t[:, None, :], (k, k, m)).ravel(),
                         np.broadcast_to(self._dofs_t[None, :, :], (k, k, m)).ravel())

    def on_members(self, members, node_index, n_dof):
        out = super().on_members(members, node_index, n_dof)
        out._component_major()
        return out

    def hessian_entries(self, members):
        """Indices into :meth:`hessian_pattern` of the entries of ``members`` (36 each, in block order)."""
        m = len(self.conn)
        return (np.arange(36)[None, :] * m + np.asarray(members, dtype=np.int64)[:, None]).ravel()

    def hessian_upper_pattern(self):
        """``K`` by its upper triangle on both nodes' diagonal blocks, ``-K`` in full between them (21 entries)."""
        if self._upper_pattern is None:
            d = self._dofs_t
            tri = [(i, j) for i in range(3) for j in range(i, 3)]
            pairs = np.array(tri + [(i, 3 + j) for i in range(3) for j in range(3)] + [(3 + i, 3 + j) for i, j in tri])
            mirrored = np.repeat(pairs[:, 0] != pairs[:, 1], d.shape[1])
            self._upper_pattern = (d[pairs[:, 0]].ravel(), d[pairs[:, 1]].ravel(), mirrored)
        return self._upper_pattern

    def hessian_upper_values(self, q, out=None):
        x = q[self._dofs_t]
        d = x[3:] - x[:3]
        length = np.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
        N, k = self._force(length)
        s = N / length
        m = length.size
        out = np.empty((21, m)) if out is None else out.reshape(21, m)
        # -K = (s - k) n n^T - s I
        np.multiply(d[:, None], ((s - k) / (length * length)) * d, out=out[6:15].reshape(3, 3, m))
        out[6:15:4] -= s
        np.negative(np.take(out[6:15], _UPPER, axis=0), out=out[0:6])
        out[15:21] = out[0:6]
        return out.ravel()

    def _compiled(self, q, grad=None, absolute=False) -> np.ndarray | None:
        """Twice the energy of every edge (m,), its gradient added to ``grad``, compiled
        (:func:`.rod_compiled.stretch_energies`: on the 936 edges of the n = 5 hemisphere 12 us a gradient against
        70 us, 11 us an energy against 36 us); None without numba or for another force law: the NumPy form of
        the bar."""
        from . import rod_compiled as compiled

        if not compiled.available or type(self)._force is not AxialBar._force \
                or type(self)._active is not AxialBar._active:
            return None
        return compiled.stretch_energies(q, self.dofs, self.EA, self.L, grad, absolute)

    def energy(self, q):
        e = self._compiled(q)
        return super().energy(q) if e is None else 0.5 * float(np.sum(e))

    def gradient(self, q):
        g = np.zeros(self.n_dof)
        return super().gradient(q) if self._compiled(q, g) is None else g

    def force_magnitudes(self, q):
        g = np.zeros(self.n_dof)
        return super().force_magnitudes(q) if self._compiled(q, g, absolute=True) is None else g

    @classmethod
    def upper_scatter(cls, effects, first, second):
        """A function ``add(effects, q, data)`` that adds the upper Hessian values to the data of a sparse matrix
        at the slots ``first`` (of every value) and ``second`` (of its mirror), compiled; None without numba or
        for another force law (see :meth:`~shellform.effects.rod_hinge.HingeEffect.upper_scatter`)."""
        from . import rod_compiled as compiled

        e = effects[0]
        if not compiled.available or len(effects) > 1 or type(e)._force is not AxialBar._force \
                or type(e)._active is not AxialBar._active:
            return None
        first, second = (compiled.element_major(a, 21) for a in (first, second))

        def add(effects, q: np.ndarray, data: np.ndarray) -> None:
            e, = effects
            compiled.add_stretch_values(q, e.dofs, np.asarray(e.EA, dtype=float), e.L, data, first, second)

        return add

    def hessian_values(self, q):
        """``[[K, -K], [-K, K]]`` with ``K = (EA / L - N / l) n n^T + (N / l) I`` (see :mod:`~shellform.effects.axial`)."""
        x = q[self._dofs_t]
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
