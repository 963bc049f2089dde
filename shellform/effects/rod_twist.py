"""Twisting of discrete elastic rods (Eq. 1c of the gridshell paper).

At every interior node ``i``: ``E_t = GJ_i / (2 dl_i) (tau_i - tau_bar_i)^2`` with
the integrated twist ``tau_i = theta^i - theta^{i-1} + m_i``, ``m_i`` the
reference twist of the time-parallel reference frames, ``dl_i`` the rest
Voronoi length and ``tau_bar_i`` the natural twist. The twist rate is
``tau / dl`` and the torque ``GJ (tau - tau_bar) / dl``.

``m_i`` depends on the positions; its exact gradient and Hessian at any trial
state (not only at the stored one) come from the spherical-triangle form of
the holonomy in :mod:`shellform.effects.rod_kinematics`, so the Hessian of this
effect is exact, including the coupling of twist to bending that drives twist
buckling.
"""

from __future__ import annotations

import numpy as np

from .rod_hinge import HingeEffect, reference_twist_derivatives, reference_twist_hessian
from .base import LineResults
from .rod_output import edge_means


class RodTwisting(HingeEffect):
    """Twisting of all hinges of all rods at once.

    Parameters
    ----------
    n_dof, frames, stencil, voronoi
        As for :class:`~shellform.effects.rod_hinge.HingeEffect`.
    GJ : ndarray (h,)
        Torsional stiffness [N m^2].
    natural_twist : ndarray (h,)
        Integrated natural twist ``tau_bar`` [rad].
    """

    name = "rod_twist"

    def __init__(self, n_dof, frames, stencil, voronoi, GJ, natural_twist):
        super().__init__(n_dof, frames, stencil, voronoi, GJ)
        self.GJ = np.asarray(GJ, dtype=float)
        self.tau_bar = np.asarray(natural_twist, dtype=float)

    def twist(self, q: np.ndarray) -> np.ndarray:
        """Integrated twist ``tau`` of every hinge at ``q``."""
        theta = q[self.stencil[:, 9:]]
        return theta[:, 1] - theta[:, 0] + self.frames.reference_twist(q)

    def _local(self, q, order):
        if order == 0:
            return (self.k * (self.twist(q) - self.tau_bar) ** 2,)
        t0, t1, l0, l1, theta = self._geometry(q)
        stored = np.ascontiguousarray(self.frames.tangent.T)
        s0, s1 = (np.take(stored, self.hinge_edges[:, j], axis=1) for j in (0, 1))
        terms = reference_twist_derivatives(t0, t1, l0, l1, s0, s1, order)
        dtau = theta[1] - theta[0] + self.frames.twist + terms.beta - self.tau_bar
        k2 = 2.0 * self.k
        c = k2 * dtau
        n = len(dtau)
        g = np.empty((8, n))
        np.multiply(c, terms.grad, out=g[:6])
        np.negative(c, out=g[6])
        g[7] = c
        H = None
        if order == 2:
            # tau's gradient over z is (grad beta, -1, 1)
            H = np.empty((8, 8, n))
            reference_twist_hessian(t0, t1, s0, terms, c, self.k, out=H[:6, :6])
            np.multiply(-k2, terms.grad, out=H[:6, 6])
            np.multiply(k2, terms.grad, out=H[:6, 7])
            H[6:, :6] = H[:6, 6:].swapaxes(0, 1)
            H[6, 6] = H[7, 7] = k2
            H[6, 7] = H[7, 6] = -k2
        return self.k * dtau**2, g, H

    def member_results(self, q):
        tau = self.twist(q)
        return {"twist_rate": tau / self.voronoi, "torque": self.GJ * (tau - self.tau_bar) / self.voronoi}

    def line_results(self, q):
        res = self.member_results(q)
        n = len(self.frames.edges)
        both = np.stack([res["torque"], res["torque"]], axis=1)
        rate = np.stack([res["twist_rate"], res["twist_rate"]], axis=1)
        return LineResults(self.frames.edges, "rod", {
            "torque": edge_means(both, self.hinge_edges, n),
            "twist_rate": edge_means(rate, self.hinge_edges, n),
        })
