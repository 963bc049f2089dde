"""Bending of discrete elastic rods (Eq. 1b of the gridshell paper), isotropic or not.

At every interior node ``i`` with rest Voronoi length ``dl_i`` and the material
curvature of each of its two edges ``omega_i^j = (kb_i . m2^j, -kb_i . m1^j)``
(integrated, dimensionless; ``kb`` the curvature binormal),

    E_b = sum_i 1 / (4 dl_i) sum_{j in {i-1, i}} sum_k EI_k (omega_k^j - omega_bar_k^j)^2,

``EI_1`` the stiffness of ``omega_1`` (the rod turning towards ``m1``), ``EI_2``
that of ``omega_2``: ``1/2 EI (kappa - kappa_bar)^2 dl`` per component with the
curvature per unit length ``kappa = omega / dl``, averaged over the frames of
the two edges (Bergou et al. 2008). With the mean ``a = (EI_1 + EI_2) / 2``
and half the difference ``d = (EI_1 - EI_2) / 2``, and ``|omega^j| = |kb|``,

    E_b = a / (2 dl) (|kb|^2 - kb . (W^{i-1} + W^i) + const)
          + d / (4 dl) sum_j ((omega_1^j)^2 - (omega_2^j)^2),
    W^j = (EI_1 / a) omega_bar_1^j m2^j - (EI_2 / a) omega_bar_2^j m1^j.

An isotropic rod (``d = 0``) that is straight when unstressed has a bending
energy independent of its material frames: bending and twist are coupled only
through the natural curvature and the reference twist. An anisotropic hinge
sees its material frames whatever its natural curvature. The gradient and
Hessian are exact, including the dependence of the time-parallel reference
frames on the positions (:mod:`shellform.effects.rod_hinge`); each material
curvature and its derivatives come from
:func:`~shellform.effects.rod_material_frame.material_curvature_term`.
"""

from __future__ import annotations

import numpy as np

from ..geometry.vectors import cross
from .rod_hinge import (HingeEffect, binormal_energy_derivatives, binormal_energy_hessian, project_to_edges,
                        stencil_gradient)
from .rod_material_frame import curvature_binormal_jacobian, material_curvature_term, material_curvature_value
from .rod_kinematics import curvature_binormal, material_curvatures, material_frames
from .base import LineResults
from .rod_output import EdgeSections, edge_means

#: unit natural curvatures that make ``omega_bar . omega`` the material curvature ``omega_1`` or ``omega_2``
_COMPONENT = (np.array([1.0, 0.0]), np.array([0.0, 1.0]))


class RodBending(HingeEffect):
    """Bending with natural curvature, isotropic or anisotropic, all hinges of all rods at once.

    Parameters
    ----------
    n_dof, frames, stencil, voronoi
        As for :class:`~shellform.effects.rod_hinge.HingeEffect`.
    EI : ndarray (h,)
        Bending stiffness [N m^2] of the material curvature ``omega_1``.
    natural_curvature : ndarray (h, 2, 2)
        Integrated natural material curvature ``omega_bar`` in the frame of
        the edge before (``[:, 0]``) and after (``[:, 1]``) each hinge.
    EI2 : ndarray (h,), optional
        Stiffness of ``omega_2``; default ``EI`` (isotropic).
    sections : EdgeSections, optional
        Section shapes of the rod edges: the line results then include the
        extreme-fibre stress ``max_stress``.
    """

    name = "rod_bend"

    def __init__(self, n_dof, frames, stencil, voronoi, EI, natural_curvature, EI2=None,
                 sections: EdgeSections | None = None):
        EI = np.asarray(EI, dtype=float)
        EI2 = EI if EI2 is None else np.asarray(EI2, dtype=float)
        # the isotropic part is carried by the mean stiffness (EI itself where EI2 == EI, bit for bit)
        self.aniso = np.flatnonzero(EI != EI2)
        mean = EI.copy()
        mean[self.aniso] = 0.5 * (EI[self.aniso] + EI2[self.aniso])
        super().__init__(n_dof, frames, stencil, voronoi, mean)
        self.EI, self.EI2 = EI, EI2
        self.sections = sections
        self.omega_bar = np.asarray(natural_curvature, dtype=float).reshape(-1, 2, 2)
        self._const = 0.5 * np.einsum("hjk,hjk->h", self.omega_bar, self.omega_bar)
        # the linear term of the anisotropic hinges weighs each component by EI_k / a
        self._w_bar = self.omega_bar.copy()
        a = self.aniso
        if a.size:
            weight = np.stack([EI[a], EI2[a]], axis=1) / mean[a, None]
            self._w_bar[a] = self.omega_bar[a] * weight[:, None, :]
            self._const[a] = 0.5 * np.einsum("hjk,hjk->h", self._w_bar[a], self.omega_bar[a])
        #: d / (2 a) of the anisotropic hinges: the factor of sum_j (omega_1^2 - omega_2^2) inside k (...)
        self._split = 0.5 * (EI[a] - EI2[a]) / (EI[a] + EI2[a])
        # only hinges with a natural curvature see the material frames through the linear term
        self.curved = np.flatnonzero(np.any(self._w_bar != 0.0, axis=(1, 2)))

    def _stored_frame(self, edges):
        u = self.frames.director[edges]
        s = self.frames.tangent[edges]
        return np.stack([u, cross(s, u), s], axis=2)

    def _local(self, q, order):
        t0, t1, l0, l1, theta = self._geometry(q)
        k = self.k
        res = binormal_energy_derivatives(t0, t1, l0, l1, order, k)
        e = res[0] + self._const
        if order == 0:
            if self.curved.size or self.aniso.size:
                self._add_frame_energies(t0, t1, theta, e)
            return (k * e,)
        g = np.zeros((8, len(k)))
        g[:6] = res[1]
        for sub, es, gz, _ in self._frame_terms(t0, t1, l0, l1, theta, hessian=False):
            e[sub] += es
            g[:, sub] += k[sub] * gz
        return k * e, g

    def add_hessian(self, q, acc):
        t0, t1, l0, l1, theta = self._geometry(q)
        binormal_energy_hessian(acc, self.k)
        for sub, _, _, Hz in self._frame_terms(t0, t1, l0, l1, theta, hessian=True):
            acc.whole.append((sub, self.k[sub] * Hz))

    hessian_slots = 2

    def kernel_terms(self, q):
        return {"bending": self.k}

    def _compiled_forces(self, q, grad=None, absolute=False):
        """The isotropic ``k |kb|^2`` compiled, the material-frame terms of the curved and anisotropic hinges added
        in the NumPy form (the magnitudes of the summed forces of those hinges from the NumPy form alone)."""
        if not (self.curved.size or self.aniso.size):
            return super()._compiled_forces(q, grad, absolute)
        if absolute:
            return None
        e = super()._compiled_forces(q, grad)
        if e is None:
            return None
        t0, t1, l0, l1, theta = self._geometry(q)
        extra = self._const.copy()
        if grad is None:
            self._add_frame_energies(t0, t1, theta, extra)
        else:
            for sub, es, gz, _ in self._frame_terms(t0, t1, l0, l1, theta, hessian=False):
                extra[sub] += es
                grad += np.bincount(self._dofs_t[:, sub].ravel(), weights=stencil_gradient(self.k[sub] * gz).ravel(),
                                    minlength=self.n_dof)
        e += self.k * extra
        return e

    def compiled_terms(self, q):
        if not (self.curved.size or self.aniso.size):
            return {"bending": self.k}
        t0, t1, l0, l1, theta = self._geometry(q)
        whole = [(sub, self.k[sub] * Hz) for sub, _, _, Hz in self._frame_terms(t0, t1, l0, l1, theta, hessian=True)]
        return {"bending": self.k, "whole": whole}

    def _frame_terms(self, t0, t1, l0, l1, theta, hessian):
        """The material-frame terms of the curved and of the anisotropic hinges: for each set, the hinges, their
        energies, gradients (8, n) over ``z`` and (if ``hessian``) Hessians (8, 8, n), before the factor ``k``."""
        for sub, terms in ((self.curved, self._curvature_terms), (self.aniso, self._anisotropy_terms)):
            if sub.size:
                T0, T1 = t0[:, sub].T, t1[:, sub].T
                es, gs, Hs = terms(T0, T1, curvature_binormal_jacobian(T0, T1), theta[:, sub].T)
                gz, Hz = project_to_edges(t0[:, sub], t1[:, sub], l0[sub], l1[sub], gs.T,
                                          Hs.transpose(1, 2, 0) if hessian else None)
                yield sub, es, gz, Hz

    def _add_frame_energies(self, t0, t1, theta, e) -> None:
        """Add the material-frame terms of the curved and anisotropic hinges to the energies ``e``."""
        c, a = self.curved, self.aniso
        for j in (0, 1):
            te = (t0, t1)[j]
            if c.size:
                kb = curvature_binormal(t0[:, c].T, t1[:, c].T)
                frame = self._stored_frame(self.hinge_edges[c, j])
                e[c] -= material_curvature_value(kb, te[:, c].T, frame, self._w_bar[c, j], theta[j, c])
            if a.size:
                kb = curvature_binormal(t0[:, a].T, t1[:, a].T)
                frame = self._stored_frame(self.hinge_edges[a, j])
                w1, w2 = (material_curvature_value(kb, te[:, a].T, frame, np.broadcast_to(u, (a.size, 2)),
                                                   theta[j, a]) for u in _COMPONENT)
                e[a] += self._split * (w1 * w1 - w2 * w2)

    def _curvature_terms(self, t0, t1, binormal, theta):
        """``-kb . (W^0 + W^1)`` of the curved hinges with its derivatives over the tangents (hinge-major)."""
        c = self.curved
        e, g, H = np.zeros(c.size), np.zeros((c.size, 8)), np.zeros((c.size, 8, 8))
        for j in (0, 1):
            f, gj, Hj = material_curvature_term(t0, t1, binormal, j, self._stored_frame(self.hinge_edges[c, j]),
                                                self._w_bar[c, j], theta[:, j])
            e -= f
            g -= gj
            H -= Hj
        return e, g, H

    def _anisotropy_terms(self, t0, t1, binormal, theta):
        """``d / (2 a) sum_j (omega_1^2 - omega_2^2)`` of the anisotropic hinges, with derivatives over the tangents."""
        a = self.aniso
        c = self._split
        e, g, H = np.zeros(a.size), np.zeros((a.size, 8)), np.zeros((a.size, 8, 8))
        for j in (0, 1):
            frame = self._stored_frame(self.hinge_edges[a, j])
            for sign, unit in zip((1.0, -1.0), _COMPONENT):
                f, gf, Hf = material_curvature_term(t0, t1, binormal, j, frame, np.broadcast_to(unit, (a.size, 2)),
                                                    theta[:, j])
                e += sign * c * f * f
                g += (2.0 * sign * c * f)[:, None] * gf
                H += (2.0 * sign * c)[:, None, None] * (gf[:, :, None] * gf[:, None, :] + f[:, None, None] * Hf)
        return e, g, H

    def side_moments(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Material curvature and bending moment at every hinge, in the frame of each of its edges.

        Returns ``omega / dl`` [1/m] and ``M_k = EI_k (omega_k - omega_bar_k) / dl``
        [N m], both of shape (h, 2, 2): hinge, edge (before, after), component
        (``k = 1``: the rod turning towards ``m1``, a moment about ``m2``;
        ``k = 2``: towards ``m2``, about ``m1``). The bending energy is
        ``sum_j dl (M_1^2 / EI_1 + M_2^2 / EI_2) / 4`` over the two edges.
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
        EI = np.stack([self.EI, self.EI2], axis=1)[:, None, :]
        return omega / dl, EI * (omega - self.omega_bar) / dl

    def member_results(self, q):
        """Per hinge: curvatures and moments (components averaged over the two edges' frames)."""
        kappa, M = self.side_moments(q)
        k, m = kappa.mean(axis=1), M.mean(axis=1)
        return {
            # |omega^j| = |kb| on both edges
            "curvature": np.linalg.norm(kappa[:, 0], axis=1),
            "curvature_1": k[:, 0],
            "curvature_2": k[:, 1],
            # root mean square over the two edges
            "bending_moment": np.sqrt(0.5 * np.sum(M * M, axis=(1, 2))),
            "bending_moment_1": m[:, 0],
            "bending_moment_2": m[:, 1],
        }

    def line_results(self, q):
        kappa, M = self.side_moments(q)
        n = len(self.frames.edges)
        k, m = edge_means(kappa, self.hinge_edges, n), edge_means(M, self.hinge_edges, n)
        fields = {
            "curvature_1": k[:, 0],
            "curvature_2": k[:, 1],
            "bending_moment_1": m[:, 0],
            "bending_moment_2": m[:, 1],
            "bending_moment": np.hypot(m[:, 0], m[:, 1]),
        }
        if self.sections is not None:
            _, length = self.frames.tangents(q)
            fields["max_stress"] = self.sections.max_stress(length, m[:, 0], m[:, 1])
        return LineResults(self.frames.edges, "rod", fields)
