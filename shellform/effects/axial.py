"""Axial two-node members: elastic bars and tension-only ropes.

Strain measure: engineering strain on the current length,
``eps = (l - L) / L`` with ``l`` the current and ``L`` the rest length, and
energy ``E = 1/2 EA L eps^2`` (the stretching energy of Eq. 1a of the
gridshell paper). The axial force is ``N = EA eps`` and the member gradient and
tangent are

    dE/dx_b = N n,        K_bb = (EA / L) n n^T + (N / l) (I - n n^T),

with ``n`` the unit vector from node a to node b; the blocks for node a follow
by the sign pattern ``[[K, -K], [-K, K]]``. The second term is the geometric
stiffness that lets a hanging net carry load transverse to its ropes.

A rope (MRA, Eqs. 3-4) has the same law while taut (``l > L``) and zero force
and stiffness while slack. The ropes' piecewise model that a relaxation step is
solved in lives with the relaxation (:mod:`shellform.solvers.relaxation.ropes`).
"""

from __future__ import annotations

import copy

import numpy as np

from .base import Effect, LineResults, element_pattern, scatter

#: the upper triangle of a 3 x 3 block, as flat indices
_UPPER = np.array([0, 1, 2, 4, 5, 8])


def two_node_blocks(K: np.ndarray) -> np.ndarray:
    """Member Hessians ``[[K, -K], [-K, K]]`` from the 3 x 3 blocks ``K`` (m, 3, 3), flattened."""
    block = np.empty((len(K), 6, 6))
    block[:, :3, :3] = K
    block[:, 3:, 3:] = K
    block[:, :3, 3:] = -K
    block[:, 3:, :3] = -K
    return block.ravel()


class _AxialMembers(Effect):
    #: kind of the members in output files, and the results written on them
    member_kind = "bar"
    written_results = ("axial_force", "strain")

    def __init__(self, n_dof: int, connectivity, EA, rest_length):
        super().__init__(n_dof)
        self.conn = np.asarray(connectivity, dtype=np.int64)
        self.EA = np.asarray(EA, dtype=float)
        self.L = np.asarray(rest_length, dtype=float)
        self.dofs = np.concatenate([3 * self.conn[:, :1] + np.arange(3), 3 * self.conn[:, 1:] + np.arange(3)], axis=1)
        self._pattern = element_pattern(self.dofs)

    def on_members(self, members: np.ndarray, node_index: np.ndarray, n_dof: int):
        """The same law on some of the members, in another numbering of the nodes.

        Parameters
        ----------
        members : ndarray of int
            Indices of the members to keep.
        node_index : ndarray of int
            New number of every node of this effect's numbering (-1 where
            unused); every end node of a kept member must have one.
        n_dof : int
            Size of the DOF vector of the new numbering.
        """
        out = copy.copy(self)
        out.n_dof = int(n_dof)
        out.conn = node_index[self.conn[members]]
        if out.conn.size and out.conn.min() < 0:
            raise ValueError("on_members: an end node of a kept member has no new number")
        out.EA = self.EA[members]
        out.L = self.L[members]
        out.dofs = np.concatenate([3 * out.conn[:, :1] + np.arange(3), 3 * out.conn[:, 1:] + np.arange(3)], axis=1)
        out._pattern = element_pattern(out.dofs)
        return out

    # force law -------------------------------------------------------------
    def _active(self, length: np.ndarray) -> np.ndarray:
        """Members that carry force at this length."""
        return np.ones(length.shape, dtype=bool)

    def _end_difference(self, v, dofs=None):
        """Second end minus first end of a DOF vector ``v``, per member (of ``dofs``, default all)."""
        dofs = self.dofs if dofs is None else dofs
        return v[dofs[:, 3:]] - v[dofs[:, :3]]

    def _geometry(self, q, dofs=None):
        """Member vectors and lengths (of the members whose end DOFs are ``dofs``, default all)."""
        d = self._end_difference(q, dofs)
        length = np.sqrt(np.einsum("ij,ij->i", d, d))
        return d, length

    def _force(self, length):
        k = np.where(self._active(length), self.EA / self.L, 0.0)
        return k * (length - self.L), k

    # effect face -----------------------------------------------------------
    def energy(self, q):
        _, length = self._geometry(q)
        N, k = self._force(length)
        return 0.5 * float(np.sum(k * (length - self.L) ** 2))

    def energy_change(self, q0, q1) -> float:
        """``energy(q1) - energy(q0)`` without the cancellation of two totals.

        ``l1 - l0 = (x1 - x0) . (x1 + x0) / (l1 + l0)`` for the member vectors
        ``x``, so a small change of length keeps its digits however long the
        member; the change of ``1/2 k d^2`` (``d`` the extension) is then
        ``1/2 k (d1 - d0)(d1 + d0)`` for a member active at both states.
        """
        return float(np.sum(self.member_energy_changes(q0, q1)))

    def member_energy_changes(self, q0, q1) -> np.ndarray:
        """Each member's share of :meth:`energy_change`, shape (m,)."""
        x0 = self._end_difference(q0)
        dx = self._end_difference(q1 - q0)
        x1 = x0 + dx
        l0 = np.sqrt(np.einsum("ij,ij->i", x0, x0))
        l1 = np.sqrt(np.einsum("ij,ij->i", x1, x1))
        a0, a1 = self._active(l0), self._active(l1)
        d0 = np.where(a0, l0 - self.L, 0.0)
        d1 = np.where(a1, l1 - self.L, 0.0)
        dl = np.einsum("ij,ij->i", dx, x0 + x1) / np.maximum(l0 + l1, 1e-300)
        diff = np.where(a0 & a1, dl, d1 - d0)
        return 0.5 * (self.EA / self.L) * diff * (d1 + d0)

    def _end_forces(self, q):
        """Force of every member on its six end DOFs, shape (m, 6)."""
        d, length = self._geometry(q)
        N, _ = self._force(length)
        f = (N / length)[:, None] * d  # = N n, the pull of the member on node a
        return np.concatenate([-f, f], axis=1)

    def gradient(self, q):
        return scatter(self.n_dof, self.dofs, self._end_forces(q))

    def force_magnitudes(self, q):
        return scatter(self.n_dof, self.dofs, np.abs(self._end_forces(q)))

    def hessian_pattern(self):
        return self._pattern

    @staticmethod
    def hessian_entries(members):
        """Indices into :meth:`hessian_pattern` of the entries of ``members`` (36 each, in block order)."""
        return (36 * np.asarray(members, dtype=np.int64)[:, None] + np.arange(36)).ravel()

    def hessian_values(self, q):
        d, length = self._geometry(q)
        N, k = self._force(length)
        n = d / length[:, None]
        nn = n[:, :, None] * n[:, None, :]
        K = (k - N / length)[:, None, None] * nn + (N / length)[:, None, None] * np.eye(3)
        return two_node_blocks(K)

    def member_results(self, q):
        _, length = self._geometry(q)
        N, _ = self._force(length)
        return {"axial_force": N, "strain": (length - self.L) / self.L, "length": length}

    def line_results(self, q):
        res = self.member_results(q)
        return LineResults(self.conn, self.member_kind, {k: res[k] for k in self.written_results})

    def held_measures(self, q):
        """Member lengths and their gradients over the six end-node DOFs."""
        d, length = self._geometry(q)
        n = d / length[:, None]
        return length, self.dofs, np.concatenate([-n, n], axis=1)


class AxialBar(_AxialMembers):
    """Linear-elastic bars carrying tension and compression.

    Parameters
    ----------
    n_dof : int
        Size of the global DOF vector.
    connectivity, EA, rest_length : array_like, shapes (m, 2), (m,), (m,)
        End nodes, axial stiffness [N] and unstressed length [m] of each bar
        (the fields of a :class:`~shellform.model.MemberGroup`).
    """

    name = "axial"

    #: members from which the bars' energy, forces and tangent values are compiled (numba). Against the
    #: NumPy law with its upper triangles summed by the System's 0/1 matrix, the kernels save 0.67 ms per
    #: tangent and two residuals at 4,236 bars, 2.6 ms at 17,166, but loading them costs a process 0.44 s
    #: once (``benchmarks/bench_bar_assembly.py``): from this size about 200 assemblies, a path of some
    #: 100 Newton iterations, pay it. By size alone, so that a model is assembled the same way in every
    #: process, whatever ran before.
    compiled_from = 15000

    def _compiles(self) -> bool:
        if len(self.L) < self.compiled_from:
            return False
        from . import rod_compiled

        return rod_compiled.available

    def _dofs_columns(self) -> np.ndarray:
        """The end DOFs by component, (6, m): worked out once per set of members (``on_members`` makes another)."""
        cached = self.__dict__.get("_columns")
        if cached is None or cached[0] is not self.dofs:
            cached = self._columns = (self.dofs, np.ascontiguousarray(self.dofs.T))
        return cached[1]

    def hessian_upper_pattern(self):
        """``K`` by its upper triangle on both nodes' diagonal blocks, ``-K`` in full between them (21 entries).

        About half the values of the full 6 x 6 blocks, summed into the CSR data by the System's constant
        0/1 matrix, or from :attr:`compiled_from` members by :meth:`upper_scatter`'s compiled loop: a free
        tangent of the 20-ring lattice dome (4,236 bars) in 0.38 ms (0.25 ms compiled) against 1.07 ms
        from the full blocks, of the 40-ring one (17,166 bars) in 1.7 ms (1.0 ms) against 6.4 ms
        (``benchmarks/results/bench_bar_assembly.md``).
        """
        return self._upper_pattern()

    def _upper_pattern(self):
        cached = self.__dict__.get("_upper")
        if cached is None or cached[0] is not self.dofs:
            d = self._dofs_columns()
            tri = [(i, j) for i in range(3) for j in range(i, 3)]
            pairs = np.array(tri + [(i, 3 + j) for i in range(3) for j in range(3)] + [(3 + i, 3 + j) for i, j in tri])
            mirrored = np.repeat(pairs[:, 0] != pairs[:, 1], d.shape[1])
            cached = self._upper = (self.dofs, (d[pairs[:, 0]].ravel(), d[pairs[:, 1]].ravel(), mirrored))
        return cached[1]

    def hessian_upper_values(self, q, out=None):
        x = q[self._dofs_columns()]
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
        """Twice the energy of every member (m,), its gradient added to ``grad``, compiled
        (:func:`.rod_compiled.stretch_energies`: on the 936 edges of the n = 5 hemisphere 12 us a gradient against
        70 us, 11 us an energy against 36 us); None without numba or for another force law: the NumPy form."""
        if not self._compiles() or type(self)._force is not AxialBar._force \
                or type(self)._active is not AxialBar._active:
            return None
        from . import rod_compiled as compiled

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
        at the slots ``first`` (of every value) and ``second`` (of its mirror), compiled; None below
        :attr:`compiled_from` members, without numba or for another force law (the System then sums the values
        by its constant 0/1 matrix; see :meth:`~shellform.effects.rod_hinge.HingeEffect.upper_scatter`)."""
        from . import rod_compiled as compiled

        e = effects[0]
        if not e._compiles() or len(effects) > 1 or type(e)._force is not AxialBar._force \
                or type(e)._active is not AxialBar._active:
            return None
        first, second = (compiled.element_major(a, 21) for a in (first, second))

        def add(effects, q: np.ndarray, data: np.ndarray) -> None:
            e, = effects
            compiled.add_stretch_values(q, e.dofs, np.asarray(e.EA, dtype=float), e.L, data, first, second)

        return add


class Rope(_AxialMembers):
    """Tension-only ropes: the bar law while taut, no force and no stiffness while slack."""

    name = "rope"
    member_kind = "rope"
    written_results = ("axial_force", "strain", "slack")

    def _active(self, length):
        return length > self.L

    def member_results(self, q):
        out = super().member_results(q)
        out["slack"] = (~self._active(out["length"])).astype(np.int8)
        return out

    def held_measures(self, q):
        # a rope may go slack within a step: its length is not held
        return None
