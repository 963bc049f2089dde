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
