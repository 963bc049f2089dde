"""The upper Hessians of rod hinges (isotropic bending and twisting) and rod edges (stretching), and the hinges'
energies and gradients, compiled.

The same closed-form terms as :class:`~shellform.effects.rod_stencil.HingeHessian`
(:func:`~shellform.effects.rod_hinge.binormal_energy_hessian` and
:func:`~shellform.effects.rod_reference_twist.reference_twist_hessian`), each
written out for one hinge at a time: the blocks of ``U`` over the edge vectors
(the Hessian being ``U + U^T``), each a sum of outer products
``t0 P^T + t1 Q^T + ...`` of which bending and twisting add up the right
vectors first, then the 66 entries
:data:`~shellform.effects.rod_stencil.UPPER_PAIRS` of the stencil Hessian.
Over 10^3 - 10^4 hinges the NumPy form spends its time in some 150 array
operations and their temporaries (1.5 - 2.5 us each whatever the size); one
pass over the hinges takes about 0.2 us per hinge
(``benchmarks/bench_rods.py --part tangent``).

The values are written to the ``(66, h)`` array of
:meth:`~shellform.effects.rod_hinge.HingeEffect.hessian_upper_values`, or
added straight into the data of the System's sparse tangent
(:meth:`~shellform.effects.rod_hinge.HingeEffect.upper_scatter`), which saves
the buffer of values and the product that sums them into the data.

The energies and gradients of the same hinges (:func:`hinge_forces`) take
their kinematics straight from the DOF vector, once per hinge, and add the
stencil forces straight into the gradient: on the hemisphere's 926 hinges
(n = 5) 40 us for the bending gradient and 70 us for the twisting one
(the two arctangents of the reference twist most of it), against 160-180 us
and 220 us in the NumPy form; an energy costs about as much as a gradient
(the arctangents again).

Vectors are tuples of three floats, which the compiler keeps in registers.
Without numba (:data:`available` False) the hinge effects take the NumPy form.
"""

from __future__ import annotations

import numpy as np

from .rod_reference_twist import TwistInputs

try:
    from numba import njit
except ImportError:  # the NumPy form of the same terms is used
    njit = None

#: whether the kernels can be compiled (numba installed)
available = njit is not None


def _jit(f):
    """Compiled on first call and cached on disk (about 3 s once, then 0.2-0.3 s per process to load); without
    numba the function stays plain Python and is not called.

    ``error_model = "numpy"``: a division by zero gives inf or nan, as in the NumPy form, for the checks of
    non-finite forces to name (numba's default raises ZeroDivisionError from inside the kernel: a degenerate
    rod, a section of 3e-11 m, then ended a run with a traceback).
    """
    if njit is None:
        return f
    try:
        return njit(cache=True, nogil=True, error_model="numpy")(f)
    except RuntimeError:  # no writable place for the cache: compiled in every process
        return njit(nogil=True, error_model="numpy")(f)


@_jit
def dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@_jit
def cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


@_jit
def add(a, b):
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


@_jit
def sub(a, b):
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


@_jit
def mul(s, a):
    return (s * a[0], s * a[1], s * a[2])


ZERO = (0.0, 0.0, 0.0)


@_jit
def block(W, l0, r0, l1, r1, l2, r2, l3, r3, d):
    """``W = l0 r0^T + l1 r1^T + l2 r2^T + l3 r3^T + d I`` (3 x 3)."""
    for a in range(3):
        for b in range(3):
            W[a, b] = l0[a] * r0[b] + l1[a] * r1[b] + l2[a] * r2[b] + l3[a] * r3[b]
        W[a, a] += d


@_jit
def bending(t0, t1, i0, i1, c, k):
    """``U`` of ``k |kb|^2`` (:func:`~shellform.effects.rod_hinge.binormal_energy_hessian`): its blocks
    ``00, 01, 10, 11`` as ``t0 P^T + t1 Q^T + d I``; returns the vectors ``P`` and ``Q`` and the ``d`` of the
    blocks ``00, 01, 11``."""
    s2 = 2.0 * k
    ichi = 1.0 / (1.0 + c)
    u = 1.0 - c
    kk = 4.0 * u * ichi
    p = 4.0 * ichi - kk
    r = 4.0 * c * ichi + kk
    # (m / l_a) (p t_a - r t_b) times y_b = ((1 - c) t_b + 2 t_b') / l_b, b' the other edge
    m0, m1 = -s2 * ichi * ichi * i0, -s2 * ichi * ichi * i1
    y0, y1 = add(mul(u * i0, t0), mul(2.0 * i0, t1)), add(mul(u * i1, t1), mul(2.0 * i1, t0))
    # -(k |kb|^2 / chi^2) v v^T, v = (w / l0, w / l1), w = t0 + t1 (so its left vectors are t0 and t1 alike)
    w = add(t0, t1)
    f = -0.5 * s2 * kk * ichi * ichi
    v0, v1 = mul(f * i0 * i0, w), mul(f * i1 * i1, w)
    v01 = mul(f * i0 * i1, w)  # = v10
    ca0, ca1 = s2 * ichi * i0 * i0, s2 * ichi * i1 * i1
    alpha = s2 * ichi * i0 * i1
    pk = p - 0.5 * kk
    ar, a4 = alpha * r, 4.0 * alpha * ichi
    P00 = add(add(mul(m0 * p, y0), v0), sub(mul(ca0 * r, t1), mul(ca0 * pk, t0)))
    Q00 = add(add(mul(-m0 * r, y0), v0), mul(-2.0 * ichi * ca0, t1))
    P01 = add(add(mul(m0 * p, y1), v01), add(mul(ar, t0), mul(alpha * kk + a4, t1)))
    Q01 = add(add(mul(-m0 * r, y1), v01), mul(-a4, t0))
    P10 = add(mul(-m1 * r, y0), v01)
    Q10 = add(add(mul(m1 * p, y0), v01), sub(mul(ar, t1), mul(a4, t0)))
    P11 = add(add(mul(-m1 * r, y1), v1), mul(-2.0 * ichi * ca1, t0))
    Q11 = add(add(mul(m1 * p, y1), v1), sub(mul(ca1 * r, t0), mul(ca1 * pk, t1)))
    d = 2.0 * ichi - 0.5 * kk
    return P00, Q00, P01, Q01, P10, Q10, P11, Q11, d * ca0, -ar, d * ca1


@_jit
def reference_twist(t0, t1, i0, i1, c, s0, s1, n2, d2, s1s0):
    """The change ``beta`` of the reference twist from the stored state and its gradient ``g0, g1`` over the edge
    vectors (:func:`~shellform.effects.rod_reference_twist.reference_twist_derivatives`), with the terms its
    Hessian is built from."""
    gn0, gn1 = cross(t1, s0), cross(s0, t0)
    N1, N2 = dot(t0, gn0), dot(t1, n2)
    s0t1 = dot(s0, t1)
    D1 = 1.0 + c + dot(s0, t0) + s0t1
    gd0, gd1 = add(s0, t1), add(s0, t0)
    R1 = N1 * N1 + D1 * D1
    D2 = 1.0 + s0t1 + dot(s1, t1) + s1s0
    R2 = N2 * N2 + D2 * D2
    G2 = sub(mul(D2, n2), mul(N2, d2))
    beta = -2.0 * (np.arctan2(N1, D1) + np.arctan2(N2, D2))
    # the gradient of beta over the tangents and over the edge vectors
    e1, e2 = -2.0 / R1, 2.0 / R2
    gt0 = mul(e1, sub(mul(D1, gn0), mul(N1, gd0)))
    gt1 = sub(mul(e1, sub(mul(D1, gn1), mul(N1, gd1))), mul(e2, G2))
    gtt0, gtt1 = dot(gt0, t0), dot(gt1, t1)
    g0, g1 = mul(i0, sub(gt0, mul(gtt0, t0))), mul(i1, sub(gt1, mul(gtt1, t1)))
    return beta, g0, g1, gn0, gn1, gd0, gd1, N1, D1, R1, N2, D2, R2, G2, gt0, gt1, gtt0, gtt1


@_jit
def twisting(t0, t1, i0, i1, c, k, s0, s1, n2, d2, s1s0, dtheta, tau_bar):
    """``U`` of ``k (tau - tau_bar)^2``
    (:func:`~shellform.effects.rod_reference_twist.reference_twist_hessian`): the gradient ``g0, g1`` of
    ``beta`` over the edge vectors, the right vectors of ``g`` (``y``) and of ``(0, x)`` (``z``), the terms
    ``t0 P^T`` of the block ``00`` and ``01`` and ``t1 Q^T`` of ``10`` and ``11``, the ``d`` of the
    blocks ``00, 01, 11``, the skew part of ``01`` (``[a]_x``) and ``2 k``."""
    beta, g0, g1, gn0, gn1, gd0, gd1, N1, D1, R1, N2, D2, R2, G2, gt0, gt1, gtt0, gtt1 = reference_twist(
        t0, t1, i0, i1, c, s0, s1, n2, d2, s1s0)
    cc = 2.0 * k * (dtheta + beta - tau_bar)
    # b: the gradient of R1 over the edge vectors
    r0, r1 = add(mul(N1, gn0), mul(D1, gd0)), add(mul(N1, gn1), mul(D1, gd1))
    b0, b1 = mul(2.0 * i0, sub(r0, mul(dot(r0, t0), t0))), mul(2.0 * i1, sub(r1, mul(dot(r1, t1), t1)))
    f = 0.5 * cc / R1
    y0, y1 = sub(mul(k, g0), mul(f, b0)), sub(mul(k, g1), mul(f, b1))
    x = mul(i1, sub(G2, mul(dot(G2, t1), t1)))
    e = -cc / (R1 * R2)
    r2 = add(mul(N2, n2), mul(D2, d2))
    r2 = mul(2.0 * cc / (R2 * R2) * i1, sub(r2, mul(dot(r2, t1), t1)))
    z0, z1 = mul(e, b0), add(mul(e, b1), r2)
    # the off-diagonal block of the first triangle, 2 c P0 (D1 [s0]_x + N1 I) P1 / (R1 l0 l1)
    alpha = 2.0 * i0 * i1 / R1 * cc
    aN, aD = alpha * N1, alpha * D1
    P01 = add(sub(mul(aD, gn1), mul(aN, t0)), mul(aN * (c - D1), t1))
    Q10 = sub(mul(aD, gn0), mul(aN, t1))
    # the normalisation
    sc0, sc1 = cc * i0 * i0, cc * i1 * i1
    P00 = mul(-sc0, sub(gt0, mul(1.5 * gtt0, t0)))
    Q11 = mul(-sc1, sub(gt1, mul(1.5 * gtt1, t1)))
    return (g0, g1, y0, y1, x, z0, z1, P00, P01, Q10, Q11, -0.5 * sc0 * gtt0, aN, -0.5 * sc1 * gtt1,
            mul(aD, s0), 2.0 * k)


@_jit
def hinge_geometry(q, d):
    """The unit tangents and lengths of the two edges of the hinge with stencil DOFs ``d`` at ``q``, as
    :meth:`~shellform.effects.rod_kinematics.ReferenceFrames.hinge_tangents` computes them."""
    e0 = (q[d[3]] - q[d[0]], q[d[4]] - q[d[1]], q[d[5]] - q[d[2]])
    e1 = (q[d[6]] - q[d[3]], q[d[7]] - q[d[4]], q[d[8]] - q[d[5]])
    l0, l1 = np.sqrt(dot(e0, e0)), np.sqrt(dot(e1, e1))
    return (e0[0] / l0, e0[1] / l0, e0[2] / l0), (e1[0] / l1, e1[1] / l1, e1[2] / l1), l0, l1


@_jit
def kernel(q, dofs, kb, kt, S0, S1, N2, D2, S1S0, twist, tau_bar, out, first, second):
    """The upper stencil Hessians of the hinges with stencil DOFs ``dofs`` (h, 11) at ``q``: ``out[n h + i]``
    the value ``n`` of hinge ``i``, or, when ``first`` is not empty, added to ``out[first[i, n]]`` and
    ``out[second[i, n]]`` (but for the last slot of ``out``)."""
    h = dofs.shape[0]
    scatter = first.shape[0] > 0
    v = np.empty(66)
    bend, tw = kb.shape[0] > 0, kt.shape[0] > 0
    W00 = np.empty((3, 3))
    W01 = np.empty((3, 3))
    W10 = np.empty((3, 3))
    W11 = np.empty((3, 3))
    x01 = np.empty((3, 3))
    x12 = np.empty((3, 3))
    for i in range(h):
        d = dofs[i]
        t0, t1, l0, l1 = hinge_geometry(q, d)
        i0, i1 = 1.0 / l0, 1.0 / l1
        c = dot(t0, t1)
        P00 = Q00 = P01 = Q01 = P10 = Q10 = P11 = Q11 = ZERO
        d00 = d01 = d11 = 0.0
        g0 = g1 = y0 = y1 = x = z0 = z1 = sk = ZERO
        k2 = 0.0
        if bend:
            P00, Q00, P01, Q01, P10, Q10, P11, Q11, d00, d01, d11 = bending(t0, t1, i0, i1, c, kb[i])
        if tw:
            g0, g1, y0, y1, x, z0, z1, p00, p01, q10, q11, e00, e01, e11, sk, k2 = twisting(
                t0, t1, i0, i1, c, kt[i], (S0[0, i], S0[1, i], S0[2, i]), (S1[0, i], S1[1, i], S1[2, i]),
                (N2[0, i], N2[1, i], N2[2, i]), (D2[0, i], D2[1, i], D2[2, i]), S1S0[i],
                q[d[10]] - q[d[9]] + twist[i], tau_bar[i])
            P00, P01, Q10, Q11 = add(P00, p00), add(P01, p01), add(Q10, q10), add(Q11, q11)
            d00, d01, d11 = d00 + e00, d01 + e01, d11 + e11
        block(W00, t0, P00, t1, Q00, g0, y0, ZERO, ZERO, d00)
        block(W01, t0, P01, t1, Q01, g0, y1, ZERO, ZERO, d01)
        block(W10, t0, P10, t1, Q10, g1, y0, x, z0, 0.0)
        block(W11, t0, P11, t1, Q11, g1, y1, x, z1, d11)
        W01[0, 1] -= sk[2]
        W01[0, 2] += sk[1]
        W01[1, 0] += sk[2]
        W01[1, 2] -= sk[0]
        W01[2, 0] -= sk[1]
        W01[2, 1] += sk[0]
        # the stencil: x0 x0: A, x0 x1: B - A, x0 x2: -B, x1 x1: -(x0 x1) - (x1 x2)^T, x1 x2: B - C, x2 x2: C
        # with A, B, C the blocks 00, 01, 11 of U + U^T
        n = 0
        for a in range(3):
            for b in range(a, 3):
                v[n] = W00[a, b] + W00[b, a]
                v[39 + n] = W11[a, b] + W11[b, a]
                n += 1
        for a in range(3):
            for b in range(3):
                B = W01[a, b] + W10[b, a]
                x01[a, b] = B - (W00[a, b] + W00[b, a])
                x12[a, b] = B - (W11[a, b] + W11[b, a])
                v[6 + 3 * a + b] = x01[a, b]
                v[15 + 3 * a + b] = -B
                v[30 + 3 * a + b] = x12[a, b]
        n = 24
        for a in range(3):
            for b in range(a, 3):
                v[n] = -(x01[a, b] + x12[b, a])
                n += 1
        # the twist angles: tau's gradient over z is (grad beta, -1, 1)
        for a in range(3):
            h0, h1 = k2 * g0[a], k2 * g1[a]
            v[45 + 2 * a] = h0
            v[46 + 2 * a] = -h0
            v[51 + 2 * a] = h1 - h0
            v[52 + 2 * a] = h0 - h1
            v[57 + 2 * a] = -h1
            v[58 + 2 * a] = h1
        v[63] = k2
        v[64] = -k2
        v[65] = k2
        if scatter:
            # not at the last slot: it stands for values that are dropped and for the mirrors of entries on a
            # block's diagonal, and adding them there would chain each such addition to the one before through
            # memory (7 % of the time here, 28 % of the stretching's, at n = 5; an inlined loop, not a
            # function: 5 % faster)
            dropped = out.shape[0] - 1
            for n in range(66):
                f, g = first[i, n], second[i, n]
                if f < dropped:
                    out[f] += v[n]
                if g < dropped:
                    out[g] += v[n]
        else:
            for n in range(66):
                out[n * h + i] = v[n]


@_jit
def scatter(data, first, second, hinges, values):
    """Add the upper stencil Hessians ``values`` (66, n) of the hinges ``hinges`` to ``data`` at their slots."""
    dropped = data.shape[0] - 1
    for j in range(hinges.shape[0]):
        i = hinges[j]
        for n in range(66):
            f, g = first[i, n], second[i, n]
            if f < dropped:
                data[f] += values[n, j]
            if g < dropped:
                data[g] += values[n, j]


@_jit
def bending_gradient(t0, t1, l0, l1, c, k):
    """``|kb|^2`` and the gradient ``gb0, gb1`` of ``k |kb|^2`` over the edge vectors
    (:func:`~shellform.effects.rod_hinge.binormal_energy_derivatives`)."""
    ichi = 1.0 / (1.0 + c)
    kb = mul(2.0 * ichi, cross(t0, t1))
    kk = dot(kb, kb)
    kw = mul(kk, add(t0, t1))
    s = 2.0 * k * ichi
    return kk, mul(s / l0, sub(mul(2.0, cross(t1, kb)), kw)), mul(s / l1, sub(mul(2.0, cross(kb, t0)), kw))


@_jit
def forces_kernel(q, dofs, kb, kt, S0, S1, N2, D2, S1S0, twist, tau_bar, energy, grad, absolute):
    """The energy of every hinge to ``energy`` (h,) and, unless ``grad`` is empty, its gradient over the stencil
    DOFs ``dofs`` (h, 11) added to ``grad`` (its absolute values where ``absolute``)."""
    h = dofs.shape[0]
    forces = grad.shape[0] > 0
    bend, tw = kb.shape[0] > 0, kt.shape[0] > 0
    f = np.empty(11)
    for i in range(h):
        d = dofs[i]
        t0, t1, l0, l1 = hinge_geometry(q, d)
        c = dot(t0, t1)
        gz0 = gz1 = ZERO
        e = ct = 0.0
        if bend:
            kk, gz0, gz1 = bending_gradient(t0, t1, l0, l1, c, kb[i])
            e = kb[i] * kk
        if tw:
            s0 = (S0[0, i], S0[1, i], S0[2, i])
            beta, g0, g1 = reference_twist(t0, t1, 1.0 / l0, 1.0 / l1, c, s0, (S1[0, i], S1[1, i], S1[2, i]),
                                           (N2[0, i], N2[1, i], N2[2, i]), (D2[0, i], D2[1, i], D2[2, i]),
                                           S1S0[i])[:3]
            dtau = q[d[10]] - q[d[9]] + twist[i] + beta - tau_bar[i]
            e += kt[i] * (dtau * dtau)
            ct = 2.0 * kt[i] * dtau
            gz0, gz1 = add(gz0, mul(ct, g0)), add(gz1, mul(ct, g1))
        energy[i] = e
        if forces:
            # e^0 = x1 - x0, e^1 = x2 - x1; tau = theta^1 - theta^0 + m
            for a in range(3):
                f[a] = -gz0[a]
                f[3 + a] = gz0[a] - gz1[a]
                f[6 + a] = gz1[a]
            f[9] = -ct
            f[10] = ct
            for n in range(11):
                grad[d[n]] += abs(f[n]) if absolute else f[n]


@_jit
def add_stretch_values(q, dofs, EA, L, data, first, second):
    """Add the upper Hessians of the stretching of the rod edges to ``data`` at ``first`` and ``second``
    ((m, 21), :func:`element_major`; the last slot of ``data`` left alone), in the order of
    :meth:`~shellform.effects.rod_stretch.RodStretching.hessian_upper_pattern`: ``K`` by its upper triangle on
    both nodes, ``-K = (N / l - k) n n^T - (N / l) I`` in full between them (``k = EA / L``)."""
    v = np.empty(21)
    for j in range(L.shape[0]):
        e = dofs[j]
        d = (q[e[3]] - q[e[0]], q[e[4]] - q[e[1]], q[e[5]] - q[e[2]])
        length = np.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
        k = EA[j] / L[j]
        s = k * (length - L[j]) / length
        c = (s - k) / (length * length)
        n = 0
        for a in range(3):
            for b in range(3):
                v[6 + 3 * a + b] = d[a] * (c * d[b])
            v[6 + 4 * a] -= s
        for a in range(3):
            for b in range(a, 3):
                v[n] = -v[6 + 3 * a + b]
                v[15 + n] = v[n]
                n += 1
        dropped = data.shape[0] - 1  # as in kernel
        for n in range(21):
            f, g = first[j, n], second[j, n]
            if f < dropped:
                data[f] += v[n]
            if g < dropped:
                data[g] += v[n]


@_jit
def stretch_forces(q, dofs, EA, L, energy, grad, absolute):
    """Twice the stretching energy ``k (l - L)^2`` (``k = EA / L``) of every rod edge with end DOFs ``dofs`` (m, 6)
    to ``energy`` (m,) and, unless ``grad`` is empty, its gradient added to ``grad`` (the absolute values where
    ``absolute``), in the order of operations of :class:`~shellform.effects.axial.AxialBar`."""
    forces = grad.shape[0] > 0
    for j in range(L.shape[0]):
        e = dofs[j]
        d = (q[e[3]] - q[e[0]], q[e[4]] - q[e[1]], q[e[5]] - q[e[2]])
        length = np.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
        k = EA[j] / L[j]
        stretch = length - L[j]
        energy[j] = k * (stretch * stretch)
        if forces:
            s = k * stretch / length
            for a in range(3):
                f = s * d[a]  # the pull of the edge on its first node
                if absolute:
                    grad[e[a]] += abs(f)
                    grad[e[3 + a]] += abs(f)
                else:
                    grad[e[a]] -= f
                    grad[e[3 + a]] += f


def element_major(slots: np.ndarray, k: int) -> np.ndarray:
    """Slots of ``k`` values per element, value-major ``(k m,)`` as the patterns list them, as the kernels read
    them: element-major ``(m, k)``, int32 unless a slot does not fit."""
    a = np.reshape(slots, (k, -1)).T
    return np.ascontiguousarray(a, dtype=np.int32 if a.size == 0 or a.max() < 2**31 else np.int64)


_NO_SLOTS = np.zeros((0, 66), dtype=np.int32)
_NO_GRADIENT = np.zeros(0)


def _inputs(bending, twisting) -> tuple:
    """The kernels' arrays of the effects' terms: empty ones for an effect that is not there."""
    none, none3 = np.zeros(0), np.zeros((3, 0))
    kb = none if bending is None else np.ascontiguousarray(bending, dtype=float)
    if twisting is None:
        tw = (none, none3, none3, none3, none3, none, none, none)
    else:
        tw = tuple(np.ascontiguousarray(a, dtype=float) for a in twisting)
    return (kb, *tw)


def upper_values(q, dofs, bending: np.ndarray | None, twisting: TwistInputs | None, out: np.ndarray) -> None:
    """Write the upper stencil Hessians (66, h) of the isotropic bending (stiffness ``k``, (h,) or None) and the
    twisting (or None) of the hinges with stencil DOFs ``dofs`` (h, 11) at ``q`` to ``out``, C-contiguous.

    Needs numba (:data:`available`).
    """
    kernel(np.ascontiguousarray(q, dtype=float), dofs, *_inputs(bending, twisting), np.reshape(out, -1, copy=False),
           _NO_SLOTS, _NO_SLOTS)


def add_upper_values(q, dofs, bending: np.ndarray | None, twisting: TwistInputs | None, data: np.ndarray,
                     first: np.ndarray, second: np.ndarray) -> None:
    """Add the values of :func:`upper_values` to ``data`` at ``first`` and ``second`` ((h, 66),
    :func:`element_major`: the slots of each hinge's values and of their mirrors; the last slot of ``data``,
    which is left alone, for none)."""
    kernel(np.ascontiguousarray(q, dtype=float), dofs, *_inputs(bending, twisting), data, first, second)


def hinge_forces(q, dofs, bending: np.ndarray | None, twisting: TwistInputs | None, grad: np.ndarray | None = None,
                 absolute: bool = False) -> np.ndarray:
    """The energies (h,) of the isotropic bending (stiffness ``k``, (h,) or None) and the twisting (or None) of the
    hinges with stencil DOFs ``dofs`` (h, 11) at ``q``, their gradient added to ``grad`` (n_dof,) if given (the
    absolute values of each hinge's gradient where ``absolute``).

    Needs numba (:data:`available`).
    """
    energy = np.empty(dofs.shape[0])
    forces_kernel(np.ascontiguousarray(q, dtype=float), dofs, *_inputs(bending, twisting), energy,
                  _NO_GRADIENT if grad is None else grad, absolute)
    return energy


def stretch_energies(q, dofs, EA, L, grad: np.ndarray | None = None, absolute: bool = False) -> np.ndarray:
    """Twice the stretching energy of every rod edge (m,) with end DOFs ``dofs`` (m, 6), axial stiffness ``EA``
    and rest length ``L`` (m,) at ``q``, its gradient added to ``grad`` (n_dof,) if given (the magnitudes of the
    end forces where ``absolute``).

    Needs numba (:data:`available`).
    """
    L = np.ascontiguousarray(L, dtype=float)
    EA = np.ascontiguousarray(np.broadcast_to(np.asarray(EA, dtype=float), L.shape))
    energy = np.empty(L.shape[0])
    stretch_forces(np.ascontiguousarray(q, dtype=float), np.ascontiguousarray(dofs, dtype=np.int64), EA, L, energy,
                   _NO_GRADIENT if grad is None else grad, absolute)
    return energy
