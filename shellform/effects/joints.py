"""Penalty joints between rods (Eq. 3 of the gridshell paper).

Two nodes that should coincide (one on each rod) are tied by a zero-length
spring, ``E_c = 1/2 K_s |x_a - x_b|^2``. The gradient is ``K_s (x_a - x_b)`` on
node a (opposite on b) and the Hessian the constant block
``K_s [[I, -I], [-I, I]]``. ``K_s`` acts like a Lagrange multiplier: the joint
gap is the joint force divided by ``K_s``; the network builder sets it as a
multiple of the rods' own stiffness (:meth:`RodNetwork.add_joints`). The exact
alternative is a node shared by both rods.
"""

from __future__ import annotations

import numpy as np

from .base import Effect, LineResults, element_pattern, scatter


class PenaltyJoints(Effect):
    """Zero-length springs between node pairs.

    Parameters
    ----------
    n_dof : int
    pairs : array_like (k, 2)
        Node pairs.
    stiffness : array_like (k,)
        Spring stiffness ``K_s`` [N/m].
    """

    name = "joints"

    def __init__(self, n_dof: int, pairs, stiffness):
        super().__init__(n_dof)
        self.pairs = np.asarray(pairs, dtype=np.int64)
        self.k = np.asarray(stiffness, dtype=float)
        self.dofs = np.concatenate([3 * self.pairs[:, :1] + np.arange(3), 3 * self.pairs[:, 1:] + np.arange(3)], axis=1)
        self._pattern = element_pattern(self.dofs)
        block = np.kron(np.array([[1.0, -1.0], [-1.0, 1.0]]), np.eye(3))
        self._values = (self.k[:, None, None] * block).ravel()

    def _gap(self, q):
        return q[self.dofs[:, :3]] - q[self.dofs[:, 3:]]

    def energy(self, q):
        d = self._gap(q)
        return 0.5 * float(np.sum(self.k * np.einsum("ij,ij->i", d, d)))

    def _end_forces(self, q):
        f = self.k[:, None] * self._gap(q)
        return np.concatenate([f, -f], axis=1)

    def gradient(self, q):
        return scatter(self.n_dof, self.dofs, self._end_forces(q))

    def force_magnitudes(self, q):
        return scatter(self.n_dof, self.dofs, np.abs(self._end_forces(q)))

    def hessian_pattern(self):
        return self._pattern

    def hessian_values(self, q):
        return self._values

    def held_measures(self, q):
        """The three components of every gap: linear in ``q``, so a projected step keeps them on the straight step."""
        k = len(self.pairs)
        dofs = np.stack([self.dofs[:, :3], self.dofs[:, 3:]], axis=2).reshape(3 * k, 2)
        grads = np.tile([1.0, -1.0], (3 * k, 1))
        return self._gap(q).ravel(), dofs, grads

    def member_results(self, q):
        gap = np.linalg.norm(self._gap(q), axis=1)
        return {"gap": gap, "force": self.k * gap}

    def line_results(self, q):
        res = self.member_results(q)
        return LineResults(self.pairs, "joint", {"joint_force": res["force"], "joint_gap": res["gap"]})
