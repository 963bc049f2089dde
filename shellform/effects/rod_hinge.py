"""Exact gradients and Hessians of the bending and twisting energies of rod hinges.

A *hinge* is an interior node ``x_1`` of a rod with its two edges
``e^0 = x_1 - x_0`` and ``e^1 = x_2 - x_1`` and their twist angles
``theta^0, theta^1``: a stencil of 11 DOFs ``(x_0, x_1, x_2, theta^0, theta^1)``.

Both energies depend on the positions only through the unit tangents
``t^j = e^j / l^j`` (the rest Voronoi length is a constant). Their derivatives
are written over ``z = (e^0, e^1, theta^0, theta^1)`` in closed form, and
carried to the stencil DOFs by differences of node blocks
(:func:`stencil_gradient`, :func:`stencil_hessian`): ``e^0 = x_1 - x_0`` and
``e^1 = x_2 - x_1``, so no matrix product is needed for that step.

The chain rule through the normalisation ``t = e / l``, with the projector
``P = I - t t^T``, is

    dF/de = P g / l,
    d2F/de_a de_b = P_a H_ab P_b / (l_a l_b) - delta_ab (W_a + W_a^T) / l_a^2,
    W = t g^T + (g . t) (I / 2 - 3/2 t t^T),

``g`` and ``H`` the derivatives over the tangents taken as free 3-vectors (any
smooth extension off the unit sphere gives the same result once composed with
the normalisation). Every term of the hinge Hessians over the tangents is an
outer product of two vectors, a multiple of the identity or a cross-product
matrix, so the projections are applied to vectors, and the products
``P_0 M P_1`` of the off-diagonal blocks are expanded into outer products.
The isotropic bending and the twisting collect these terms in a
:class:`HingeHessian`, which sums the outer products of all hinges with one
batched product of small matrices and carries the sum of the effects to the
stencil once, to the upper triangle of each stencil Hessian
(:data:`UPPER_PAIRS`) for the System's tangents. Where numba is installed the
System's tangents take the same upper values from a kernel compiled per
hinge (:mod:`.rod_compiled`, :meth:`HingeEffect.upper_scatter`), added
straight into the tangent's data; the collection stays the reference and the
form without numba. The energies and gradients of the same terms are compiled
as well (:meth:`HingeEffect._compiled_forces`), with the NumPy form
(``_local``) their reference and the form without numba.

Array layout: the closed-form functions work on *component-major* arrays with
the hinge index last (vectors ``(3, h)``, Hessians ``(8, 8, h)``), so that every
arithmetic operation runs over all hinges on contiguous memory; the effects'
Hessian patterns follow the same order (entry-major, ``(11, 11, h)`` and
``(66, h)``). The layered dense form of the same derivatives (over the
tangents, then through dense 0/+-1 maps) serves as the reference in the tests.

The stencil algebra and the Hessian collector are in :mod:`.rod_stencil`, the
reference twist's derivatives in :mod:`.rod_reference_twist`, the
material-frame terms of curved and anisotropic hinges in
:mod:`.rod_material_frame`, the component-major algebra in :mod:`.rod_vectors`.

Conventions (Bergou et al. 2008): curvature binormal
``kb = 2 t^0 x t^1 / (1 + t^0 . t^1)``; material curvature of edge ``j`` at the
hinge ``omega^j = (kb . m2^j, -kb . m1^j)``; twist
``tau = theta^1 - theta^0 + m`` with ``m`` the reference twist
(:mod:`shellform.effects.rod_kinematics`).
"""

from __future__ import annotations

import numpy as np

from .base import Effect
from .rod_stencil import UPPER_PAIRS, HingeHessian, stencil_gradient, stencil_hessian, stencil_pattern, stencil_upper
from .rod_vectors import cross, inner, outer, project, subtract_curvature, view


# -- the isotropic bending term |kb|^2 over the edge vectors -------------------------------


def binormal_energy_derivatives(t0, t1, l0, l1, order=1, scale=None):
    """``|kb|^2`` and, for ``order == 1``, its gradient (6, h) over ``(e^0, e^1)``.

    With ``chi = 1 + t0 . t1`` and ``w = t0 + t1``, the Jacobian of the
    binormal over the edge vectors is
    ``K = [(-2 S_1 - kb w^T) / (chi l0), (2 S_0 - kb w^T) / (chi l1)]``
    (``S_a = [t_a]_x``), so that ``grad = 2 K^T kb``. The Hessian is
    collected by :func:`binormal_energy_hessian`.

    Parameters
    ----------
    t0, t1 : (3, h)
        Unit tangents of the two edges.
    l0, l1 : (h,)
        Their lengths.
    order : {0, 1}
    scale : (h,), optional
        Factor of the gradient of each hinge (the energy is not scaled).

    Returns
    -------
    f : (h,), and for ``order == 1`` grad : (6, h)
    """
    chi = 1.0 + inner(t0, t1)
    ichi = 1.0 / chi
    kb = (2.0 * ichi) * cross(t0, t1)
    kk = inner(kb, kb)
    if order == 0:
        return (kk,)
    s2 = 2.0 if scale is None else 2.0 * scale
    w = t0 + t1
    kw = kk * w
    gh = np.empty((6,) + kk.shape)  # K^T kb
    np.multiply(2.0 * cross(t1, kb) - kw, s2 * ichi / l0, out=gh[:3])
    np.multiply(2.0 * cross(kb, t0) - kw, s2 * ichi / l1, out=gh[3:])
    return kk, gh


def binormal_energy_hessian(acc: HingeHessian, k) -> None:
    """Add the Hessian of ``k |kb|^2`` over ``(e^0, e^1)`` to ``acc`` (two slots of its own).

    The Hessian is ``2 k (K^T K + sum_k kb_k Hess kb_k)`` with ``K`` the
    binormal's Jacobian (:func:`binormal_energy_derivatives`). For unit
    tangents ``t1 x kb = 2 (t0 - c t1) / chi`` and ``kb x t0 = 2 (t1 - c t0) / chi``
    (``c = t0 . t1 = chi - 1``) and ``|kb|^2 = 4 (1 - c) / chi``, so every
    term is an outer product of combinations of ``t0`` and ``t1``, a multiple
    of the identity, or the cross-product matrix of ``t0 x t1``, itself the
    pair of outer products ``t1 t0^T - t0 t1^T``. With ``p = 4 / chi - |kb|^2``,
    ``r = 4 c / chi + |kb|^2`` and, for block ``a`` (``b`` the other edge),
    ``U`` (the Hessian being ``U + U^T``) is

    * ``(m / l_a) (p t_a - r t_b)`` times ``(((1 - c) t_a + 2 t_b) / l_a)`` (both 6-vectors, by blocks),
      ``m = -2 k / chi^2``,
    * ``-(k |kb|^2 / chi^2) v v^T`` with ``v = (w / l0, w / l1)``, ``w = t0 + t1``,
    * in the blocks ``aa``: ``-c_a (t_a ((p - |kb|^2 / 2) t_a - r t_b)^T + (2 / chi) t_b t_b^T)``
      and ``c_a (2 / chi - |kb|^2 / 2) I``, ``c_a = 2 k / (chi l_a^2)``,
    * in the block ``01``: ``alpha (t0 (r t0 + (|kb|^2 + 4 / chi) t1)^T + (r t1 - 4 t0 / chi) t1^T
      - (4 / chi) t1 t0^T - r I)``, ``alpha = 2 k / (chi l0 l1)``.
    """
    T, Tr, inv, c = acc.T, acc.T[::-1], acc.inv, acc.cos
    s2 = 2.0 * k
    ichi = 1.0 / (1.0 + c)
    u = 1.0 - c
    kk = 4.0 * u * ichi
    p = 4.0 * ichi - kk
    r = 4.0 * c * ichi + kk
    X, Y = acc.claim()
    X, Y = view(X, (2, 3, -1)), view(Y, (2, 3, -1))
    mi = (-s2 * ichi * ichi) * inv
    np.subtract((mi * p)[:, None] * T, (mi * r)[:, None] * Tr, out=X)
    np.add((u * inv)[:, None] * T, (2.0 * inv)[:, None] * Tr, out=Y)
    X, Y = acc.claim()
    np.multiply(T[0] + T[1], inv[:, None], out=view(Y, (2, 3, -1)))
    np.multiply(Y, (-0.5 * s2) * kk * ichi * ichi, out=X)
    ca = (s2 * ichi) * inv * inv
    alpha = s2 * ichi * inv[0] * inv[1]
    R = acc.R
    R[0:6:5] -= (ca * (p - 0.5 * kk))[:, None] * T - (ca * r)[:, None] * Tr
    R[2:8:5] -= (2.0 * ichi * ca)[:, None] * Tr
    ar, a4 = alpha * r, 4.0 * alpha * ichi
    R[1] += ar * T[0] + (alpha * kk + a4) * T[1]
    R[4] += ar * T[1] - a4 * T[0]
    R[3] -= a4 * T[0]
    acc.diagonal[:2] += (2.0 * ichi - 0.5 * kk) * ca
    acc.diagonal[2] -= ar


# -- from the edge vectors to the stencil -----------------------------------------------------


def project_to_edges(t0, t1, l0, l1, g, H=None):
    """Carry a gradient (8, h) and Hessian (8, 8, h) over ``(t0, t1, theta0, theta1)`` to ``z``.

    The general form of the chain rule through the normalisation, for terms
    given over the tangents (the material-frame terms of curved and
    anisotropic hinges).
    """
    i0, i1 = 1.0 / l0, 1.0 / l1
    gz = g.copy()
    gz[:3] = project(g[:3], t0, i0)
    gz[3:6] = project(g[3:6], t1, i1)
    if H is None:
        return gz, None
    Hz = H.copy()
    for a, t in enumerate((t0, t1)):
        s = slice(3 * a, 3 * a + 3)
        Hz[:, s] -= outer((Hz[:, s] * t).sum(axis=1), t)
        Hz[s] -= outer(t, (Hz[s] * t[:, None]).sum(axis=0))
    scale = np.ones_like(g)
    scale[:3] = i0
    scale[3:6] = i1
    Hz *= outer(scale, scale)
    for a, (t, ia) in enumerate(((t0, i0), (t1, i1))):
        s = slice(3 * a, 3 * a + 3)
        W = np.zeros((3, 3) + i0.shape)
        subtract_curvature(W, t, g[s], -ia * ia)
        Hz[s, s] -= W + W.swapaxes(0, 1)
    return gz, Hz


# -- common machinery of the hinge effects ------------------------------------------------


class HingeEffect(Effect):
    """Base of the effects defined on rod hinges (11-DOF stencils) with shared reference frames.

    The energy of hinge ``i`` is ``k_i f_i`` with ``k_i = stiffness_i / (2 dl_i)``.
    Subclasses implement ``_local(q, order)`` returning the energy per hinge
    (h,) and, for ``order >= 1``, its gradient (8, h) over
    ``z = (e0, e1, theta0, theta1)`` (component-major), and
    :meth:`add_hessian`, which adds the Hessian over ``z`` to a
    :class:`HingeHessian` (by default the Hessian (8, 8, h) of
    ``_local(q, 2)``). The Hessian values of effects on the same hinges are
    collected together and carried to the stencil once
    (:meth:`summed_hessian_upper_values`).

    Parameters
    ----------
    n_dof : int
    frames : ReferenceFrames
        Shared reference state of the rod edges.
    stencil : ndarray (h, 11)
        DOFs ``(x0, x1, x2, theta0, theta1)`` of every hinge.
    voronoi : ndarray (h,)
        Rest Voronoi lengths ``dl`` [m].
    stiffness : ndarray (h,)
        Bending or torsional stiffness [N m^2].
    """

    def __init__(self, n_dof, frames, stencil, voronoi, stiffness):
        super().__init__(n_dof)
        self.frames = frames
        self.stencil = np.ascontiguousarray(stencil, dtype=np.int64)  # read by the compiled kernels hinge by hinge
        self.hinge_edges = frames.hinges
        self._dofs_t = np.ascontiguousarray(self.stencil.T)
        self._pattern = stencil_pattern(self.stencil)
        self._upper_pattern = None
        self._scratch = {}  # HingeHessian arrays reused between evaluations, by number of slots
        self._last_forces = None  # (q, the terms' arrays, energies) of the last compiled gradient
        self.voronoi = np.asarray(voronoi, dtype=float)
        self.k = np.asarray(stiffness, dtype=float) / (2.0 * self.voronoi)

    def _geometry(self, q):
        """Tangents (3, h) and lengths (h,) of both edges of every hinge, and the twist angles (2, h)."""
        t0, t1, l0, l1 = self.frames.hinge_tangents(q)
        return t0, t1, l0, l1, q[self._dofs_t[9:]]

    def energy(self, q):
        e = self._compiled_forces(q)
        return float(np.sum(self._local(q, 0)[0] if e is None else e))

    def _stencil_forces(self, q):
        """Gradient of every hinge's energy on its 11 stencil DOFs, shape (11, h)."""
        return stencil_gradient(self._local(q, 1)[1])

    def gradient(self, q):
        g = np.zeros(self.n_dof)
        if self._compiled_forces(q, g) is None:
            return np.bincount(self._dofs_t.ravel(), weights=self._stencil_forces(q).ravel(), minlength=self.n_dof)
        return g

    def force_magnitudes(self, q):
        g = np.zeros(self.n_dof)
        if self._compiled_forces(q, g, absolute=True) is None:
            return np.bincount(self._dofs_t.ravel(), weights=np.abs(self._stencil_forces(q)).ravel(),
                               minlength=self.n_dof)
        return g

    def _compiled_forces(self, q, grad=None, absolute=False) -> np.ndarray | None:
        """The energy of every hinge (h,), its gradient added to ``grad`` if given (the magnitudes of each hinge's
        forces where ``absolute``), from the kernel compiled per hinge (:func:`.rod_compiled.hinge_forces`: the
        kinematics of a hinge once, straight from ``q``, and no arrays between the steps); None where numba is not
        installed or the effect has no :meth:`kernel_terms`: the NumPy form (:meth:`_local`)."""
        from . import rod_compiled as compiled

        terms = self.kernel_terms(q) if compiled.available else None
        if terms is None:
            return None
        # a solver asks for the energy where it has just asked for the gradient (a line search's trial
        # point): the energies of that pass serve, while the terms' arrays are the same objects (the
        # effects and their frames replace them, never change them in place) and q is equal
        key = tuple(a for t in terms.values() for a in (t if isinstance(t, tuple) else (t,)))
        last = getattr(self, "_last_forces", None)
        if grad is None and last is not None and len(last[1]) == len(key) \
                and all(a is b for a, b in zip(last[1], key)) and np.array_equal(last[0], q):
            return last[2].copy()
        e = compiled.hinge_forces(q, self.stencil, terms.get("bending"), terms.get("twisting"), grad, absolute)
        if grad is not None:
            self._last_forces = (np.array(q, dtype=float), key, e.copy())
        return e

    def kernel_terms(self, q: np.ndarray) -> dict | None:
        """The terms of :meth:`compiled_terms` but ``"whole"``: what the compiled kernels evaluate for this effect
        (None, the default: the NumPy form)."""
        return None

    def hessian_pattern(self):
        return self._pattern

    def hessian_values(self, q):
        return stencil_hessian(HingeEffect._hessian([self], q).full()).ravel()

    def hessian_upper_pattern(self):
        """The entries :data:`UPPER_PAIRS` of every hinge, entry-major ``(66, h)``."""
        if self._upper_pattern is None:
            rows = self._dofs_t[UPPER_PAIRS[:, 0]].ravel()
            cols = self._dofs_t[UPPER_PAIRS[:, 1]].ravel()
            mirrored = np.repeat(UPPER_PAIRS[:, 0] != UPPER_PAIRS[:, 1], self.stencil.shape[0])
            self._upper_pattern = (rows, cols, mirrored)
        return self._upper_pattern

    def hessian_upper_values(self, q, out=None):
        return HingeEffect._upper_values([self], q, out)

    @classmethod
    def summed_hessian_upper_values(cls, effects, q, out=None):
        """Bending and twisting of the same hinges: their terms evaluated together and carried to the stencil
        once (:meth:`_upper_values`)."""
        first = effects[0]
        if not all(isinstance(e, HingeEffect) and e.frames is first.frames
                   and (e.stencil is first.stencil or np.array_equal(e.stencil, first.stencil)) for e in effects):
            return super().summed_hessian_upper_values(effects, q, out)
        return HingeEffect._upper_values(effects, q, out)

    @staticmethod
    def _upper_values(effects, q, out=None) -> np.ndarray:
        """The summed upper stencil Hessians of effects on the same hinges, flat ``(66 h,)``.

        Compiled per hinge (:mod:`.rod_compiled`) when every effect
        gives its :meth:`compiled_terms` and numba is installed, collected in
        a :class:`HingeHessian` otherwise.
        """
        # imported here: numba's import alone takes 0.1-0.3 s, which models without rods never need
        from . import rod_compiled as compiled

        terms = HingeEffect._compiled_terms(effects, q) if compiled.available else None
        if terms is None:
            return HingeEffect._hessian(effects, q).upper(out).ravel()
        h = effects[0].stencil.shape[0]
        values = np.empty((66, h)) if out is None else view(out, (66, h))
        compiled.upper_values(q, effects[0].stencil, terms.get("bending"), terms.get("twisting"), values)
        for sub, H in terms["whole"]:
            values[:, sub] += stencil_upper(H)
        return values.ravel()

    @classmethod
    def upper_scatter(cls, effects, first: np.ndarray, second: np.ndarray):
        """A function ``add(effects, q, data)`` that adds the summed upper stencil Hessians of ``effects`` (on
        the same hinges) to the data of a sparse matrix, or None where it cannot (numba not installed, an
        effect without :meth:`compiled_terms`).

        ``first`` and ``second`` give, for every value of
        :meth:`hessian_upper_pattern`, the slots in ``data`` of its entry and
        of its mirror (the last slot where there is none). The function takes
        the effects when it is called: a copy of the System with copies of its
        effects (another stiffness, say) shares the slots.
        """
        from . import rod_compiled as compiled

        if not compiled.available or any(type(e).compiled_terms is HingeEffect.compiled_terms
                                         or e.frames is not effects[0].frames for e in effects):
            return None
        # hinge-major: the kernel adds the values of one hinge after the other
        first, second = (compiled.element_major(a, 66) for a in (first, second))

        def add(effects, q: np.ndarray, data: np.ndarray) -> None:
            terms = HingeEffect._compiled_terms(effects, q)
            compiled.add_upper_values(q, effects[0].stencil, terms.get("bending"), terms.get("twisting"), data,
                                      first, second)
            for sub, H in terms["whole"]:
                compiled.scatter(data, first, second, sub, stencil_upper(H))

        return add

    @staticmethod
    def _compiled_terms(effects, q) -> dict | None:
        """The :meth:`compiled_terms` of ``effects`` merged, or None if one has none or two give the same term."""
        terms = {"whole": []}
        for e in effects:
            own = e.compiled_terms(q)
            if own is None or set(own) & set(terms) - {"whole"}:
                return None
            terms.update(own, whole=terms["whole"] + own.get("whole", []))
        return terms

    def compiled_terms(self, q: np.ndarray) -> dict | None:
        """What the compiled hinge kernel takes from this effect at ``q``, or None (the default): the NumPy form.

        Keys: ``"bending"``, the stiffness ``k`` (h,) of an isotropic
        ``k |kb|^2``; ``"twisting"``, a
        :class:`~shellform.effects.rod_reference_twist.TwistInputs`;
        ``"whole"``, a list of pairs of hinge indices and Hessians over ``z``
        (8, 8, n) added as they are.
        """
        return None

    #: slots of a :class:`HingeHessian` of the effect's own
    hessian_slots = 0

    def add_hessian(self, q: np.ndarray, acc: HingeHessian) -> None:
        """Add the Hessian over ``z`` at ``q`` to ``acc``; by default the whole one, from ``_local(q, 2)``."""
        acc.whole.append((None, self._local(q, 2)[2]))

    @staticmethod
    def _hessian(effects, q) -> HingeHessian:
        """The sum of the Hessians of hinge effects on the same hinges, collected (scratch arrays of the first)."""
        first = effects[0]
        t0, t1, l0, l1 = first.frames.hinge_tangents(q)
        key = sum(e.hessian_slots for e in effects)
        acc = first._scratch.get(key)
        if acc is None:
            acc = first._scratch[key] = HingeHessian(t0.shape[1], key)
        acc.start(t0, t1, l0, l1)
        for e in effects:
            e.add_hessian(q, acc)
        return acc

    def accept(self, q: np.ndarray) -> None:
        """Make ``q`` the stored reference state (time-parallel transport of the frames)."""
        self.frames.update(q)
