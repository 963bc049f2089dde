"""Bending of discrete elastic rods (Eq. 1b of the gridshell paper).

At every interior node ``i`` with rest Voronoi length ``dl_i`` and the material
curvature of each of its two edges ``omega_i^j = (kb_i . m2^j, -kb_i . m1^j)``
(integrated, dimensionless; ``kb`` the curvature binormal),

    E_b = sum_i EI_i / (4 dl_i) sum_{j in {i-1, i}} |omega_i^j - omega_bar_i^j|^2,

i.e. ``1/2 EI (kappa - kappa_bar)^2 dl`` with the curvature per unit length
``kappa = omega / dl``, averaged over the frames of the two edges (Bergou et
al. 2008). For an isotropic section ``|omega^j| = |kb|``, so

    E_b = EI / (2 dl) (|kb|^2 - kb . (W^{i-1} + W^i) + const),
    W^j = omega_bar_1^j m2^j - omega_bar_2^j m1^j,

and a rod that is straight when unstressed has a bending energy independent of
its material frames: bending and twist are coupled only through the natural
curvature and the reference twist. The gradient and Hessian are exact,
including the dependence of the time-parallel reference frames on the
positions (:mod:`shellform.rods.hinge`).
"""

from __future__ import annotations

import numpy as np

from ..rods.hinge import (
    BinormalJacobian,
    HingeEffect,
    curvature_binormal_jacobian,
    hessian_of_projected_binormal,
    material_curvature_term,
    material_curvature_value,
)
from ..rods.kinematics import curvature_binormal, dot, material_curvatures, material_frames
from .base import LineResults
from .rod_output import edge_means


class RodBending(HingeEffect):
    """Isotropic bending with natural curvature, all hinges of all rods at once.

    Parameters
    ----------
    n_dof, frames, stencil, voronoi
        As for :class:`~shellform.rods.hinge.HingeEffect`.
    EI : ndarray (h,)
        Bending stiffness [N m^2].
    natural_curvature : ndarray (h, 2, 2)
        Integrated natural material curvature ``omega_bar`` in the frame of
        the edge before (``[:, 0]``) and after (``[:, 1]``) each hinge.
    """

    name = "rod_bend"

    def __init__(self, n_dof, frames, stencil, voronoi, EI, natural_curvature):
        super().__init__(n_dof, frames, stencil, voronoi, EI)
        self.EI = np.asarray(EI, dtype=float)
        self.omega_bar = np.asarray(natural_curvature, dtype=float).reshape(-1, 2, 2)
        # only hinges with a natural curvature see the material frames
        self.curved = np.flatnonzero(np.any(self.omega_bar != 0.0, axis=(1, 2)))
        self._const = 0.5 * np.einsum("hjk,hjk->h", self.omega_bar, self.omega_bar)

    def _stored_frame(self, edges):
        u = self.frames.director[edges]
        s = self.frames.tangent[edges]
        return np.stack([u, np.cross(s, u), s], axis=2)

    def _local(self, q, order):
        t0, t1, l0, l1, theta = self._geometry(q)
        c = self.curved
        if order == 0:
            kb = curvature_binormal(t0, t1)
            e = dot(kb, kb) + self._const
            for j, te in enumerate((t0, t1)):
                if c.size:
                    frame = self._stored_frame(self.hinge_edges[c, j])
                    e[c] -= material_curvature_value(kb[c], te[c], frame, self.omega_bar[c, j], theta[c, j])
            return (self.k * e,)
        kb, chi, J = curvature_binormal_jacobian(t0, t1)
        n = len(t0)
        e = dot(kb, kb) + self._const
        g = np.zeros((n, 8))
        g[:, :6] = 2.0 * np.einsum("nk,nka->na", kb, J)
        H = None
        if order == 2:
            H = np.zeros((n, 8, 8))
            H[:, :6, :6] = 2.0 * np.einsum("nka,nkb->nab", J, J) + 2.0 * hessian_of_projected_binormal(
                t0, t1, kb, chi, J, kb
            )
        if c.size:
            for j in (0, 1):
                edges = self.hinge_edges[c, j]
                f, gj, Hj = material_curvature_term(
                    t0[c], t1[c], BinormalJacobian(kb[c], chi[c], J[c]), j, self._stored_frame(edges),
                    self.omega_bar[c, j], theta[c, j],
                )
                e[c] -= f
                g[c] -= gj
                if H is not None:
                    H[c] -= Hj
        k = self.k
        g *= k[:, None]
        if H is not None:
            H *= k[:, None, None]
        return k * e, g, H

    def side_moments(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Material curvature and bending moment at every hinge, in the frame of each of its edges.

        Returns ``omega / dl`` [1/m] and ``M = EI (omega - omega_bar) / dl``
        [N m], both of shape (h, 2, 2): hinge, edge (before, after), component
        (about ``m1``, about ``m2``). The bending energy is
        ``sum_j dl |M^j|^2 / (4 EI)`` over the two edges.
        """
        t, _ = self.frames.tangents(q)
        u = self.frames.directors(q)
        theta = q[self.stencil[:, 9:]]
        kb = curvature_binormal(t[self.hinge_edges[:, 0]], t[self.hinge_edges[:, 1]])
        omega = np.empty((len(kb), 2, 2))
        for j in (0, 1):
            e = self.hinge_edges[:, j]
            omega[:, j] = material_curvatures(kb, *material_frames(u[e], t[e], theta[:, j]))
        dl = self.voronoi[:, None, None]
        return omega / dl, self.EI[:, None, None] * (omega - self.omega_bar) / dl

    def member_results(self, q):
        """Per hinge: curvatures and moments (components averaged over the two edges' frames)."""
        kappa, M = self.side_moments(q)
        k, m = kappa.mean(axis=1), M.mean(axis=1)
        return {
            # |omega^j| = |kb| on both edges of an isotropic rod
            "curvature": np.linalg.norm(kappa[:, 0], axis=1),
            "curvature_1": k[:, 0],
            "curvature_2": k[:, 1],
            # root mean square over the two edges: the moment the bending energy stores
            "bending_moment": np.sqrt(0.5 * np.sum(M * M, axis=(1, 2))),
            "bending_moment_1": m[:, 0],
            "bending_moment_2": m[:, 1],
        }

    def line_results(self, q):
        kappa, M = self.side_moments(q)
        n = len(self.frames.edges)
        k, m = edge_means(kappa, self.hinge_edges, n), edge_means(M, self.hinge_edges, n)
        return LineResults(self.frames.edges, "rod", {
            "curvature_1": k[:, 0],
            "curvature_2": k[:, 1],
            "bending_moment_1": m[:, 0],
            "bending_moment_2": m[:, 1],
            "bending_moment": np.hypot(m[:, 0], m[:, 1]),
        })
