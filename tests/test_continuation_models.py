"""Small truss models with closed-form equilibrium paths, shared by the continuation tests.

Every model is a shallow two-bar (von Mises) truss: supports at ``(-L, 0, 0)``
and ``(L, 0, 0)``, apex at ``(0, 0, H)``, bars of axial stiffness ``EA`` with
the engineering strain of :mod:`shellform.effects.axial`. With ``theta`` the
current bar angle (apex height ``L tan(theta)``) the bar strain is
``cos(alpha) / cos(theta) - 1`` and vertical equilibrium of the apex gives

    P(theta) = 2 EA sin(theta) (1 - cos(alpha) / cos(theta)),

with the limit point at ``cos(theta)^3 = cos(alpha)``.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import brentq, minimize_scalar

from shellform import Structure, build_system

L, H, EA = 1.0, 0.5, 1.0e6
ALPHA = np.arctan2(H, L)
THETA_CR = np.arccos(np.cos(ALPHA) ** (1.0 / 3.0))
P_CR = 2.0 * EA * np.sin(THETA_CR) ** 3


def truss_load(theta, EA=EA, alpha=ALPHA):
    """Apex load (downwards positive) in equilibrium at bar angle ``theta``."""
    return 2.0 * EA * np.sin(theta) * (1.0 - np.cos(alpha) / np.cos(theta))


def load_of_deflection(v):
    """Apex load as a function of the apex deflection ``v`` (downwards positive)."""
    return truss_load(np.arctan2(H - v, L))


def von_mises(control="load", planar=True):
    """Two-bar truss with a unit downward apex load (load control) or a prescribed apex descent.

    Load control: apex restrained in x and y, one free DOF (apex z).
    Displacement control: apex z prescribed downwards, apex x free (y fixed).
    """
    s = Structure([[-L, 0, 0], [0, 0, H], [L, 0, 0]])
    s.add_bars([[0, 1], [1, 2]], EA, name="truss")
    s.fix([0, 2])
    if control == "load":
        s.fix([1], "xy" if planar else "y")
        s.add_load([1], [0, 0, -1.0])
    else:
        s.fix([1], "y")
        s.prescribe_dofs([5], [-1.0])
    return build_system(s)


# -- snap-back: the truss loaded through a soft spring -----------------------------------
LS = 1.0  # spring length


def spring_truss(ks_ratio=0.05, control="load"):
    """Truss whose apex carries a vertical spring bar (stiffness ``ks = ks_ratio EA / L``) loaded at its top.

    The load-point displacement is ``w = v + P / ks``. For ``ks`` below the
    largest softening slope of the truss, ``2 EA (1 - cos(alpha)) / L``, the
    path in ``(w, P)`` turns back in both load and displacement (snap-back).
    Node 3 is the spring top; DOF 11 its z.
    """
    ks = ks_ratio * EA / L
    s = Structure([[-L, 0, 0], [0, 0, H], [L, 0, 0], [0, 0, H + LS]])
    s.add_bars([[0, 1], [1, 2]], EA, name="truss")
    s.add_bars([[1, 3]], ks * LS, name="spring")
    s.fix([0, 2])
    s.fix([1, 3], "xy")
    if control == "load":
        s.add_load([3], [0, 0, -1.0])
    else:
        s.prescribe_dofs([11], [-1.0])
    return build_system(s), ks


def spring_truss_w(theta, ks):
    """Load-point displacement along the snap-back path."""
    return H - L * np.tan(theta) + truss_load(theta) / ks


def spring_truss_w_extrema(ks):
    """Displacement ``w`` at its local maximum and minimum along the path (the snap-back points)."""
    f = lambda th: spring_truss_w(th, ks)  # noqa: E731
    wmax = -minimize_scalar(lambda th: -f(th), bounds=(0.0, ALPHA), method="bounded", options={"xatol": 1e-12}).fun
    wmin = minimize_scalar(f, bounds=(-ALPHA, 0.0), method="bounded", options={"xatol": 1e-12}).fun
    return wmax, wmin


# -- bifurcation: out-of-plane buckling held by two lateral springs ------------------------
LY = 1.0


def braced_truss(EAs=2.0e4):
    """Truss whose apex (free in x, y, z) is held out of plane by two symmetric spring bars.

    Spring bars run from the apex to fixed nodes at ``(0, +-LY, H)``. On the
    primary (in-plane) path the out-of-plane stiffness is
    ``K_yy = 2 N / l + 2 (EAs / LY n_y^2 + N_s / l_s (1 - n_y^2))``; it vanishes
    at a symmetric bifurcation before the limit point.
    """
    s = Structure([[-L, 0, 0], [0, 0, H], [L, 0, 0], [0, LY, H], [0, -LY, H]])
    s.add_bars([[0, 1], [1, 2]], EA, name="truss")
    s.add_bars([[1, 3], [1, 4]], EAs, name="braces")
    s.fix([0, 2, 3, 4])
    s.add_load([1], [0, 0, -1.0])
    return build_system(s)


def braced_primary(z, EAs=2.0e4):
    """Load and out-of-plane stiffness on the in-plane path at apex height ``z``."""
    l0 = np.hypot(L, H)
    lb = np.hypot(L, z)
    N = EA * (lb - l0) / l0
    ls = np.hypot(LY, H - z)
    Ns = EAs * (ls - LY) / LY
    P = -2.0 * N * z / lb + 2.0 * Ns * (H - z) / ls
    ny = LY / ls
    kyy = 2.0 * N / lb + 2.0 * (EAs / LY * ny**2 + Ns / ls * (1.0 - ny**2))
    return P, kyy


def braced_critical(EAs=2.0e4):
    """Analytic (load, apex height) at the first bifurcation and at the limit point."""
    zs = np.linspace(H, 0.0, 4001)
    P, _ = braced_primary(zs, EAs)
    i = int(np.argmax(P))
    res = minimize_scalar(lambda z: -braced_primary(z, EAs)[0], bounds=(zs[i + 1], zs[i - 1]), method="bounded",
                          options={"xatol": 1e-13})
    z_lim, P_lim = res.x, -res.fun
    z_bif = brentq(lambda z: braced_primary(z, EAs)[1], H * (1 - 1e-9), z_lim, xtol=1e-15)
    return (braced_primary(z_bif, EAs)[0], z_bif), (P_lim, z_lim)


def test_analytic_truss_limit_matches_published_formula():
    """The closed form used by the tests has its maximum where the analytic limit point lies."""
    th = np.linspace(0.0, ALPHA, 200001)
    P = truss_load(th)
    assert abs(P.max() - P_CR) / P_CR < 1e-9
    assert abs(th[np.argmax(P)] - THETA_CR) < 1e-4


def test_braced_truss_bifurcates_before_its_limit():
    (Pb, zb), (Pl, zl) = braced_critical()
    assert 0.0 < Pb < Pl and zb > zl
