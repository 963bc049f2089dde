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

from .rod_hinge import HingeEffect
from .rod_reference_twist import (TwistInputs, reference_twist_derivatives, reference_twist_hessian,
                                  stored_twist_terms)
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
        self._stored_cache = None

    def twist(self, q: np.ndarray) -> np.ndarray:
        """Integrated twist ``tau`` of every hinge at ``q``."""
        theta = q[self.stencil[:, 9:]]
        return theta[:, 1] - theta[:, 0] + self.frames.reference_twist(q)

    def _stored(self):
        """The stored tangents of both edges of every hinge (3, h) and :func:`stored_twist_terms` of them.

        Kept while the frames keep their array of stored tangents: they
        replace it, never change it in place, when they take a new state.
        """
        tangent = self.frames.tangent
        if self._stored_cache is None or self._stored_cache[0] is not tangent:
            stored = np.ascontiguousarray(tangent.T)
            s0, s1 = (np.take(stored, self.hinge_edges[:, j], axis=1) for j in (0, 1))
            self._stored_cache = (tangent, s0, s1, stored_twist_terms(s0, s1))
        return self._stored_cache[1:]

    def _twist_terms(self, q, order, acc=None):
        t0, t1, l0, l1, theta = self._geometry(q)
        s0, s1, stored = self._stored()
        terms = reference_twist_derivatives(t0, t1, l0, l1, s0, s1, order,
                                            *((None, None) if acc is None else (acc.T, acc.inv)), stored)
        dtau = theta[1] - theta[0] + self.frames.twist + terms.beta - self.tau_bar
        return s0, terms, dtau

    def _local(self, q, order):
        if order == 0:
            return (self.k * (self.twist(q) - self.tau_bar) ** 2,)
        _, terms, dtau = self._twist_terms(q, 1)
        c = 2.0 * self.k * dtau
        g = np.empty((8, len(dtau)))
        np.multiply(c, terms.grad, out=g[:6])
        np.negative(c, out=g[6])
        g[7] = c
        return self.k * dtau**2, g

    hessian_slots = 2

    def add_hessian(self, q, acc):
        s0, terms, dtau = self._twist_terms(q, 2, acc)
        reference_twist_hessian(acc, s0, terms, 2.0 * self.k * dtau, self.k)

    def compiled_terms(self, q):
        return self.kernel_terms(q)

    def kernel_terms(self, q):
        s0, s1, stored = self._stored()
        return {"twisting": TwistInputs(self.k, s0, s1, *stored, self.frames.twist, self.tau_bar)}

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
