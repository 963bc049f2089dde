"""Smooth curves in space through given points, and the point of a curve nearest to a node.

A support that slides along an arch or a ring holds its node on such a curve
(:mod:`shellform.effects.curve_sliding`). The curve interpolates the points
with a spline parametrised by chord length: cubic through four points or
more (periodic when the last point repeats the first, so a ring has no
corner), a parabola through three, the straight segment between two.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
from scipy.interpolate import BSpline, make_interp_spline

from ..errors import ModelError

#: samples per span of the interpolated points from which the nearest point starts its Newton iterations:
#: enough that the start lies in the basin of the nearest point wherever a node is closer to the curve than
#: the curve's radius of curvature
SAMPLES_PER_SPAN = 16
#: Newton iterations of the nearest point (quadratic convergence: a start in the basin needs 4 to 6)
NEAREST_ITERATIONS = 30
#: most golden-section steps where Newton does not settle (each shrinks the bracket by 0.618: 1e-14 in 70)
GOLDEN_ITERATIONS = 100


@dataclass(frozen=True)
class SpaceCurve:
    """A spline curve in space, parameter ``t`` in ``[0, length of the polygon of its points]``.

    Attributes
    ----------
    spline : scipy.interpolate.BSpline
        The curve, ``spline(t)`` of shape (..., 3).
    closed : bool
        Periodic: ``t`` wraps around, the curve has no ends.
    spans : int
        Number of intervals between the interpolated points.
    """

    spline: BSpline
    closed: bool
    spans: int

    @classmethod
    def through(cls, points, what: str = "curve") -> "SpaceCurve":
        """The curve through ``points`` (k, 3); closed when the last point repeats the first."""
        p = np.asarray(points, dtype=float)
        if p.ndim != 2 or p.shape[1] != 3 or len(p) < 2:
            raise ModelError(f"{what}: needs at least two points [x, y, z], got an array of shape {p.shape}")
        if not np.all(np.isfinite(p)):
            raise ModelError(f"{what}: point {int(np.flatnonzero(~np.isfinite(p).all(axis=1))[0])} is not finite")
        chord = np.linalg.norm(np.diff(p, axis=0), axis=1)
        if np.any(chord == 0.0):
            raise ModelError(f"{what}: points {int(np.argmin(chord))} and {int(np.argmin(chord)) + 1} coincide")
        t = np.concatenate([[0.0], np.cumsum(chord)])
        closed = len(p) > 3 and bool(np.all(p[0] == p[-1]))
        if closed:
            spline = make_interp_spline(t, p, k=3, bc_type="periodic")
        else:
            spline = make_interp_spline(t, p, k=min(3, len(p) - 1))
        return cls(spline, closed, len(p) - 1)

    @property
    def domain(self) -> tuple[float, float]:
        k = self.spline.k
        return float(self.spline.t[k]), float(self.spline.t[-k - 1])

    def __call__(self, t, nu: int = 0) -> np.ndarray:
        """Points (``nu = 0``) or derivatives with respect to ``t`` at the parameters ``t``."""
        return self.spline(self._wrap(np.asarray(t, dtype=float)), nu)

    def _wrap(self, t):
        a, b = self.domain
        return a + np.mod(t - a, b - a) if self.closed else t

    def transformed(self, matrix, shift) -> "SpaceCurve":
        """The curve moved by ``x -> matrix @ x + shift`` (a spline's points move with its control points)."""
        c = self.spline.c @ np.asarray(matrix, dtype=float).T + np.asarray(shift, dtype=float)
        return SpaceCurve(BSpline(self.spline.t, c, self.spline.k, extrapolate=self.spline.extrapolate),
                          self.closed, self.spans)

    @cached_property
    def _samples(self):
        """Dense samples of the parameter and a k-d tree of their points (built once, on first use)."""
        from scipy.spatial import cKDTree

        a, b = self.domain
        samples = np.linspace(a, b, SAMPLES_PER_SPAN * self.spans + 1)
        return samples, cKDTree(self.spline(samples))

    def nearest(self, x) -> tuple[np.ndarray, np.ndarray]:
        """Parameter of the point of the curve nearest to each of ``x`` (n, 3), and whether it is an end.

        The nearest of dense samples starts Newton's method on ``c'(t) . (c(t) - x) = 0``; an open curve's
        parameter stays within its ends, where the nearest point may be an end itself. A node for which
        Newton does not settle (where the distance is nearly flat along the curve, next to its centre of
        curvature) gets the minimum of the distance between the samples either side of its nearest
        sample, by golden-section search: the spring's force is then still normal to the curve, where an
        unsettled Newton iterate would have left a tangential force in the equilibrium.
        """
        x = np.asarray(x, dtype=float).reshape(-1, 3)
        a, b = self.domain
        samples, tree = self._samples
        t0 = samples[tree.query(x)[1]]
        scale = b - a
        t = t0.copy()
        settled = np.zeros(len(t), dtype=bool)
        for _ in range(NEAREST_ITERATIONS):
            r = self(t) - x
            c1, c2 = self(t, 1), self(t, 2)
            f = np.einsum("ni,ni->n", c1, r)
            df = np.einsum("ni,ni->n", c1, c1) + np.einsum("ni,ni->n", c2, r)
            # beyond the curve's centre of curvature the distance has a maximum there: step on its slope only
            step = f / np.where(df > 0.0, df, np.einsum("ni,ni->n", c1, c1))
            t_new = t - step
            if not self.closed:
                t_new = np.clip(t_new, a, b)
            settled = np.abs(t_new - t) <= 1e-14 * scale
            t = t_new
            if np.all(settled):
                break
        if not np.all(settled):
            spacing = samples[1] - samples[0]
            k = np.flatnonzero(~settled)
            t[k] = self._golden_nearest(x[k], t0[k] - spacing, t0[k] + spacing)
        end = np.zeros(len(t), dtype=bool) if self.closed else (t <= a) | (t >= b)
        return self._wrap(t), end

    def _golden_nearest(self, x, lo, hi) -> np.ndarray:
        """The parameter in ``[lo, hi]`` (clipped to an open curve's ends) nearest to each of ``x``: golden section."""
        a, b = self.domain
        if not self.closed:
            lo, hi = np.clip(lo, a, b), np.clip(hi, a, b)
        ratio = (np.sqrt(5.0) - 1.0) / 2.0

        def distance(t):
            return np.linalg.norm(self(t) - x, axis=1)

        c, d = hi - ratio * (hi - lo), lo + ratio * (hi - lo)
        fc, fd = distance(c), distance(d)
        for _ in range(GOLDEN_ITERATIONS):
            if not np.any(hi - lo > 1e-14 * (b - a)):
                break
            left = fc < fd  # the minimum lies in [lo, d]: d becomes hi, c becomes d
            hi, lo = np.where(left, d, hi), np.where(left, lo, c)
            c_new, d_new = hi - ratio * (hi - lo), lo + ratio * (hi - lo)
            c, d, f_old_c, f_old_d = np.where(left, c_new, d), np.where(left, c, d_new), fc, fd
            fc = np.where(left, distance(c), f_old_d)
            fd = np.where(left, f_old_c, distance(d))
        t = 0.5 * (lo + hi)
        # the distance is flat at its minimum, so comparing it places t to about 1e-8 only: bisection on its
        # slope c'(t) . (c(t) - x), which crosses zero there, finishes the job where it changes sign
        lo, hi = t - 1e-6 * (b - a), t + 1e-6 * (b - a)
        if not self.closed:
            lo, hi = np.clip(lo, a, b), np.clip(hi, a, b)

        def slope(t):
            return np.einsum("ni,ni->n", self(t, 1), self(t) - x)

        bracketed = (slope(lo) < 0.0) & (slope(hi) > 0.0)
        for _ in range(GOLDEN_ITERATIONS):
            if not np.any(bracketed & (hi - lo > 1e-15 * (b - a))):
                break
            mid = 0.5 * (lo + hi)
            right = slope(mid) > 0.0
            hi, lo = np.where(right, mid, hi), np.where(right, lo, mid)
        return np.where(bracketed, 0.5 * (lo + hi), t)
