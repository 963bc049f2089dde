"""Chebyshev nets on a sphere: the geometry of the hemispherical gridshell.

A Chebyshev net is a parametrisation ``x(u, v)`` of a surface in which both
families of coordinate lines are parametrised by arc length
(``|x_u| = |x_v| = 1``). Rods that are straight and inextensible in the plane,
laid out as a square grid and pinned to each other at the crossings, take
exactly this shape when they are bent onto the surface: distances between
joints along a rod do not change (Baek, Sageman-Furnas, Jawed and Reis 2018).

We build the net of the gridshell paper: two orthogonal great circles through
the apex generate it, and the rest follows by the discrete compass
construction. With step ``delta``, ``P[i, j]`` is the point on the sphere at
chord distance ``c`` from both ``P[i-1, j]`` and ``P[i, j-1]`` (the fourth
corner of a rhombus), ``c`` being the chord of a great-circle arc ``delta``. As
``delta -> 0`` this converges to the smooth net (error O(delta^2)); joints are
the net points every ``m = h / delta`` steps.

Rod ``k`` of family ``"u"`` (``"v"``) is the net line ``j = k m`` (``i = k m``);
in the plane it is the straight segment ``y = k h`` (``x = k h``) and the joint
with rod ``l`` of the other family sits at arc length ``l h`` from the
crossing with the central rod. Rods are cut where they reach the equator.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ModelError
from .vectors import cross


@dataclass(frozen=True)
class Rod:
    """One rod of the net.

    Attributes
    ----------
    family : {"u", "v"}
        ``"u"`` rods run along x in the plane, ``"v"`` rods along y.
    index : int
        Signed rod number; the rod sits at offset ``index * h`` in the plane.
    s_start, s_end : float
        Arc-length coordinates of the rod's ends (zero at the crossing with the
        central rod of the other family) [m].
    points : ndarray, shape (p, 3)
        Fine polyline of the rod on the sphere from ``s_start`` to ``s_end``.
    s : ndarray, shape (p,)
        Arc-length coordinate of each point.
    """

    family: str
    index: int
    s_start: float
    s_end: float
    points: np.ndarray
    s: np.ndarray

    @property
    def length(self) -> float:
        return self.s_end - self.s_start

    def position(self, s) -> np.ndarray:
        """Point(s) of the rod at arc-length coordinate(s) ``s`` (linear between net points)."""
        s = np.asarray(s, dtype=float)
        return np.stack([np.interp(s, self.s, self.points[:, c]) for c in range(3)], axis=-1)

    def planar(self, s, h: float) -> np.ndarray:
        """Position in the flat footprint at arc-length coordinate(s) ``s`` (z = 0)."""
        s = np.asarray(s, dtype=float)
        offset = np.full_like(s, self.index * h)
        xy = (s, offset) if self.family == "u" else (offset, s)
        return np.stack([*xy, np.zeros_like(s)], axis=-1)


@dataclass(frozen=True)
class Joint:
    """A crossing of rod ``u_index`` (family u) with rod ``v_index`` (family v).

    On the u rod the joint is at arc length ``v_index * h``, on the v rod at
    ``u_index * h``.
    """

    u_index: int
    v_index: int
    position: np.ndarray


@dataclass(frozen=True)
class ChebyshevHemisphere:
    """The Chebyshev net of a hemispherical gridshell with ``n`` rods per direction."""

    radius: float
    n: int
    spacing: float
    rods: tuple[Rod, ...]
    joints: tuple[Joint, ...]
    delta: float

    def rod(self, family: str, index: int) -> Rod:
        for r in self.rods:
            if r.family == family and r.index == index:
                return r
        raise KeyError(f"no rod {family}{index}")

    @property
    def rod_lengths(self) -> np.ndarray:
        return np.array([r.length for r in self.rods])

    def footprint(self) -> list[np.ndarray]:
        """Planar end points of every rod, ``[(2, 3) array, ...]`` in rod order."""
        return [r.planar([r.s_start, r.s_end], self.spacing) for r in self.rods]

    def equator_ends(self) -> list[np.ndarray]:
        """End points of every rod on the equator, ``[(2, 3) array, ...]`` in rod order."""
        return [r.points[[0, -1]] for r in self.rods]


def _compass_net(radius: float, delta: float, half: int) -> np.ndarray:
    """Discrete Chebyshev net ``P[i, j]`` for ``i, j`` in ``-half..half``.

    Points outside the domain where the construction exists are NaN.
    """
    R = radius
    size = 2 * half + 1
    P = np.full((size, size, 3), np.nan)
    ang = np.arange(-half, half + 1) * delta / R
    P[:, half] = R * np.column_stack([np.sin(ang), np.zeros(size), np.cos(ang)])  # u line: xz great circle
    P[half, :] = R * np.column_stack([np.zeros(size), np.sin(ang), np.cos(ang)])  # v line: yz great circle
    c = 2.0 * R * np.sin(0.5 * delta / R)
    k = R**2 - 0.5 * c**2  # x . A = x . B = k for the rhombus corner x
    # the four quadrants (signs si, sj) filled together along anti-diagonals: every point needs the two
    # neighbours one step closer to the axes. One pass over the anti-diagonals for all four, not one per
    # quadrant: the work per anti-diagonal is small, and at n = 11 the four passes took 0.59 s
    signs = np.array([(-1, -1), (-1, 1), (1, -1), (1, 1)])
    for d in range(2, 2 * half + 1):
        a = np.arange(max(1, d - half), min(half, d - 1) + 1)
        si = np.repeat(signs[:, 0], a.size)
        sj = np.repeat(signs[:, 1], a.size)
        i = half + si * np.tile(a, 4)
        j = half + sj * np.tile(d - a, 4)
        A = P[i - si, j]
        B = P[i, j - sj]
        D = P[i - si, j - sj]
        g = np.einsum("ij,ij->i", A, B)
        alpha = k / (R**2 + g)
        AxB = cross(A, B)
        beta2 = (R**2 - alpha**2 * (2 * R**2 + 2 * g)) / np.einsum("ij,ij->i", AxB, AxB)
        with np.errstate(invalid="ignore"):
            beta = np.sqrt(beta2)
        x1 = alpha[:, None] * (A + B) + beta[:, None] * AxB
        x2 = alpha[:, None] * (A + B) - beta[:, None] * AxB
        # the other solution is the old corner D (the rhombus folded back)
        far1 = np.einsum("ij,ij->i", x1 - D, x1 - D) >= np.einsum("ij,ij->i", x2 - D, x2 - D)
        P[i, j] = np.where(far1[:, None], x1, x2)
    return P


def _cut_at_equator(points: np.ndarray, s: np.ndarray, centre: int):
    """Keep the part of a net line around ``centre`` that stays above z = 0,
    ending exactly on the equator (linear interpolation of the last step)."""
    z = points[:, 2]
    ok = np.isfinite(z) & (z > 0)
    if not ok[centre]:
        raise ModelError("a rod's crossing with the central rod lies below the equator")
    lo = centre
    while lo > 0 and ok[lo - 1]:
        lo -= 1
    hi = centre
    while hi < len(z) - 1 and ok[hi + 1]:
        hi += 1
    if lo == 0 or hi == len(z) - 1 or not (np.isfinite(z[lo - 1]) and np.isfinite(z[hi + 1])):
        raise ModelError("the Chebyshev net does not reach the equator along this rod; use a finer step")

    def crossing(inside, outside):
        t = z[inside] / (z[inside] - z[outside])
        return points[inside] + t * (points[outside] - points[inside]), s[inside] + t * (s[outside] - s[inside])

    p0, s0 = crossing(lo, lo - 1)
    p1, s1 = crossing(hi, hi + 1)
    pts = np.vstack([p0, points[lo : hi + 1], p1])
    ss = np.concatenate([[s0], s[lo : hi + 1], [s1]])
    return pts, ss


def chebyshev_hemisphere(radius: float, n: int, spacing: float | None = None, delta: float | None = None):
    """The Chebyshev net of a hemispherical gridshell.

    Parameters
    ----------
    radius : float
        Sphere radius R [m].
    n : int
        Rods per direction (odd: the central rods pass through the apex).
    spacing : float, optional
        Distance h between neighbouring joints along a rod. Default
        ``pi R / (n + 1)``: the rods through the apex (length ``pi R``) are cut
        into ``n + 1`` equal pieces by the ``n`` crossing rods and the equator.
    delta : float, optional
        Step of the compass construction; default about ``h / 64`` (it must
        divide ``h``; it is rounded so that it does).

    Returns
    -------
    ChebyshevHemisphere
    """
    if not (np.isfinite(radius) and radius > 0):
        raise ModelError(f"hemisphere: radius must be positive, got {radius}")
    if int(n) != n or n < 1 or n % 2 == 0:
        raise ModelError(f"hemisphere: rods per direction n must be a positive odd integer, got {n}")
    n = int(n)
    h = np.pi * radius / (n + 1) if spacing is None else float(spacing)
    if not (h > 0 and (n - 1) / 2 * h < 0.5 * np.pi * radius):
        raise ModelError(f"hemisphere: spacing {h} puts the outer rods beyond the equator")
    m = max(4, int(round(h / (delta if delta is not None else h / 64))))
    delta = h / m
    half = int(np.ceil(0.5 * np.pi * radius / delta)) + 2
    P = _compass_net(radius, delta, half)
    s_axis = np.arange(-half, half + 1) * delta
    rods, kmax = [], (n - 1) // 2
    for family in ("u", "v"):
        for k in range(-kmax, kmax + 1):
            line = P[:, half + k * m] if family == "u" else P[half + k * m, :]
            pts, ss = _cut_at_equator(line, s_axis, half)
            rods.append(Rod(family, k, float(ss[0]), float(ss[-1]), pts, ss))
    joints = []
    for ku in range(-kmax, kmax + 1):
        for kv in range(-kmax, kmax + 1):
            p = P[half + kv * m, half + ku * m]
            if np.all(np.isfinite(p)) and p[2] > 0:
                joints.append(Joint(ku, kv, p.copy()))
    return ChebyshevHemisphere(radius, n, h, tuple(rods), tuple(joints), delta)
