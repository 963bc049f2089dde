"""Validation cases of the discrete elastic rods: elastica, Euler and Greenhill buckling, torsion,
a rectangular section bent about each axis and the lateral-torsional buckling of a narrow cantilever."""

from __future__ import annotations

import numpy as np
from scipy.optimize import brentq

from ..model import Structure
from ..rods.network import RodNetwork, build_rod_system
from ..rods.section import RestShape, RodSection, section_of
from ..geometry.sections import rectangle
from ..rods.statics import solve_incremental
from ..solvers.newton import solve_static
from .reference import (
    CANTILEVER_SELF_WEIGHT,
    CANTILEVER_SOURCE,
    CANTILEVER_TOLERANCE,
    EULER_EFFECTIVE_LENGTH,
    EULER_SOURCE,
    GREENHILL_SOURCE,
    GREENHILL_TORQUE,
    PRANDTL_COEFFICIENT,
    PRANDTL_SOURCE,
    ROD_BUCKLING_TOLERANCE,
)
from .report import CaseResult, Check

G = 9.81


def straight_rod(stations, EA: float, EI: float = 1.0, GJ: float = 1.0 / 1.3, mass_per_length: float = 0.0):
    """One rod along x through the given arc-length stations."""
    stations = np.asarray(stations, dtype=float)
    s = Structure(np.stack([stations, 0 * stations, 0 * stations], axis=1))
    net = RodNetwork(s)
    net.add_rod(np.arange(len(stations)), RodSection(EA=EA, EI=EI, GJ=GJ, mass_per_length=mass_per_length))
    return s, net


def clamped_stations(n: int, L: float = 1.0, both: bool = False) -> np.ndarray:
    """Stations of ``n`` edges with the clamped end edge astride s = 0 (and s = L when
    ``both``): a clamp fixes an edge, whose frame lives at its midpoint."""
    h = L / (n - 1.0) if both else L / (n - 0.5)
    return (np.arange(n + 1) - 0.5) * h


def self_weight_cantilever(alpha: float, n: int = 40, L: float = 1.0, EI: float = 1.0):
    """Horizontally clamped rod under its weight, ``alpha = rho A g L^3 / EI``."""
    s, net = straight_rod(clamped_stations(n, L), EA=1e5 * EI / L**2, EI=EI,
                          mass_per_length=alpha * EI / (G * L**3))
    net.clamp(0, "start")
    s.set_gravity((0.0, 0.0, -G))
    return s, net


def cantilever_tip(alpha: float, n: int = 40):
    """Tip (x, z) / L of the self-weight cantilever and the solver result."""
    s, net = self_weight_cantilever(alpha, n)
    system = build_rod_system(net, gravity_scaled=True)
    res = solve_incremental(system, lam=1.0, n_steps=1 if alpha < 20 else 3)
    tip = res.q[3 * (s.n_nodes - 1): 3 * s.n_nodes]
    return float(tip[0]), float(tip[2]), res


def euler_column(case: str, n: int = 40, EA: float = 1e6, L: float = 1.0):
    """Straight column of unit EI under an end load along -x (the load factor is P)."""
    st = np.linspace(0.0, L, n + 1) if case == "pinned-pinned" else clamped_stations(n, L, both=case == "clamped-clamped")
    s, net = straight_rod(st, EA=EA)
    if case == "pinned-pinned":
        net.pin(0, "start", twist="fixed")
        s.fix([n], "yz")
        s.add_load([n], [-1.0, 0, 0])
    elif case == "clamped-free":
        net.clamp(0, "start")
        s.add_load([n], [-1.0, 0, 0])
    elif case == "clamped-pinned":
        net.clamp(0, "start")
        s.fix([n], "yz")
        s.add_load([n], [-1.0, 0, 0])
    elif case == "clamped-clamped":  # the far clamp slides along x: both its nodes carry half the load
        net.clamp(0, "start")
        s.fix([n - 1, n], "yz")
        net.fix_twist(0, "end")
        s.add_load([n - 1, n], [-0.5, 0, 0])
    else:
        raise ValueError(f"unknown column case {case!r}; expected one of {list(EULER_EFFECTIVE_LENGTH)}")
    return s, build_rod_system(net)


def lowest_eigenvalue(system, **static_options) -> float:
    """Smallest eigenvalue of the free tangent at the static equilibrium."""
    res = solve_static(system, **static_options)
    if not res.success:
        raise RuntimeError(res.message)
    return float(np.linalg.eigvalsh(system.tangent_free(res.q).toarray())[0])


def critical_parameter(system, guess: float, parameter: str) -> float:
    """Where the lowest eigenvalue of the tangent crosses zero (``parameter`` is
    ``"lam"`` or ``"mu"``), bracketed within 20 % of ``guess``."""
    return brentq(lambda p: lowest_eigenvalue(system, **{parameter: p}), 0.8 * guess, 1.2 * guess, xtol=1e-10 * guess)


def greenhill_column(n: int = 40, EI: float = 1.0, GJ: float = 2.0 / 3.0):
    """Rod clamped at both ends, one end turned about the axis by ``mu`` radians."""
    s, net = straight_rod(clamped_stations(n, both=True), EA=1e6, EI=EI, GJ=GJ)
    net.clamp(0, "start")
    net.clamp(0, "end")
    rod = net.rods[0]
    s.prescribe_dofs([rod.twist_dofs[-1]], [1.0])
    return build_rod_system(net)


#: the rectangle of the section checks: depth along m1 twice the width along m2 (EI1 = 4 EI2)
RECTANGLE = {"depth": 0.02, "width": 0.01, "E": 1.0e10, "G": 1.0e10 / 2.6}


def rectangular_cantilever(alpha: float, axis: int, n: int = 40, L: float = 1.0):
    """Horizontal rectangular cantilever along x under self-weight bending about section axis ``axis``.

    The section's first director ``m1`` is vertical (``axis = 1``: the rod
    turns towards ``m1``, stiffness ``EI1``) or horizontal (``axis = 2``:
    stiffness ``EI2``); the density is chosen so that
    ``alpha = rho A g L^3 / EI_axis``.
    """
    shape = rectangle(RECTANGLE["depth"], RECTANGLE["width"])
    EI = RECTANGLE["E"] * (shape.I1 if axis == 1 else shape.I2)
    density = alpha * EI / (G * L**3 * shape.area)
    section = section_of(shape, RECTANGLE["E"], RECTANGLE["G"], density)
    stations = clamped_stations(n, L)
    s = Structure(np.stack([stations, 0 * stations, 0 * stations], axis=1))
    net = RodNetwork(s)
    director = (0.0, 0.0, 1.0) if axis == 1 else (0.0, 1.0, 0.0)
    net.add_rod(np.arange(len(stations)), section, RestShape(director=director))
    net.clamp(0, "start")
    s.set_gravity((0.0, 0.0, -G))
    return s, net


def rectangular_cantilever_tip(alpha: float, axis: int, n: int = 40):
    """Tip (x, y, z) / L of :func:`rectangular_cantilever` and the solver result."""
    s, net = rectangular_cantilever(alpha, axis, n)
    res = solve_incremental(build_rod_system(net, gravity_scaled=True), lam=1.0, n_steps=1 if alpha < 20 else 3)
    return res.q[3 * (s.n_nodes - 1): 3 * s.n_nodes].copy(), res


def narrow_cantilever(n: int = 40, L: float = 1.0, depth: float = 0.04, width: float = 0.001):
    """Cantilever of a narrow rectangle (depth along the vertical m1) under a vertical end load P (the load factor).

    Returns the system and ``sqrt(EI_min GJ) / L^2``, the scale of Prandtl's critical load.
    """
    E = 3.0e11
    shape = rectangle(depth, width)
    section = section_of(shape, E, E / 2.6)
    stations = clamped_stations(n, L)
    s = Structure(np.stack([stations, 0 * stations, 0 * stations], axis=1))
    net = RodNetwork(s)
    net.add_rod(np.arange(len(stations)), section, RestShape(natural_curvature="straight", director=(0, 0, 1)))
    net.clamp(0, "start")
    s.add_load([n], [0.0, 0.0, -1.0])
    # the clamp sits half an edge inside the first edge: the cantilever is L long
    return build_rod_system(net), np.sqrt(section.EI2 * section.GJ) / L**2


def case_rods(out) -> CaseResult:
    res = CaseResult("rods", "discrete elastic rods: elastica under self-weight, Euler and Greenhill buckling")
    iterations = []
    for alpha, (x_ref, z_ref) in CANTILEVER_SELF_WEIGHT.items():
        x, z, r = cantilever_tip(alpha)
        iterations.append(sum(r.iterations))
        res.checks.append(Check(f"self-weight cantilever, alpha = {alpha:g}: tip x/L", x, x_ref,
                                CANTILEVER_TOLERANCE, relative=False, source=CANTILEVER_SOURCE))
        res.checks.append(Check(f"self-weight cantilever, alpha = {alpha:g}: tip z/L", z, z_ref,
                                CANTILEVER_TOLERANCE, relative=False, source=CANTILEVER_SOURCE))
    for case, K in EULER_EFFECTIVE_LENGTH.items():
        exact = np.pi**2 / K**2
        _, system = euler_column(case)
        res.checks.append(Check(f"Euler buckling, {case}: P_cr L^2 / EI", critical_parameter(system, exact, "lam"),
                                exact, ROD_BUCKLING_TOLERANCE, source=EULER_SOURCE))
    EI, GJ = 1.0, 2.0 / 3.0
    phi = critical_parameter(greenhill_column(EI=EI, GJ=GJ), GREENHILL_TORQUE * EI / GJ, "mu")
    res.checks.append(Check("Greenhill twist buckling, clamped-clamped: M_cr L / EI", GJ * phi, GREENHILL_TORQUE,
                            ROD_BUCKLING_TOLERANCE, source=GREENHILL_SOURCE))
    for axis in (1, 2):
        for alpha in (1.0, 10.0):
            tip, _ = rectangular_cantilever_tip(alpha, axis)
            x_ref, z_ref = CANTILEVER_SELF_WEIGHT[alpha]
            for k, ref, name in ((0, x_ref, "x"), (2, z_ref, "z")):
                res.checks.append(Check(f"rectangular cantilever about axis {axis}, alpha = {alpha:g}: tip {name}/L",
                                        float(tip[k]), ref, CANTILEVER_TOLERANCE, relative=False,
                                        source=CANTILEVER_SOURCE))
    system, scale = narrow_cantilever()
    P = critical_parameter(system, PRANDTL_COEFFICIENT * scale, "lam")
    res.checks.append(Check("lateral-torsional buckling of a narrow cantilever: P_cr L^2 / sqrt(EI_min GJ)",
                            P / scale, PRANDTL_COEFFICIENT, ROD_BUCKLING_TOLERANCE, source=PRANDTL_SOURCE))
    res.notes = (
        "40 edges per rod, EA L^2/EI = 1e5 (cantilever) and 1e6 (columns). Buckling loads are where the "
        "lowest eigenvalue of the free tangent at the straight equilibrium crosses zero. Cantilever Newton "
        f"iterations: {', '.join(map(str, iterations))}. The effective length K = 0.699 (clamped-pinned) is the "
        "rounded tabulated value; the exact root of tan x = x gives K = 0.6992. The rectangle is 20 x 10 mm "
        "(EI1 = 4 EI2), bent by its weight towards m1 (axis 1) or m2 (axis 2). The narrow cantilever is 40 x 1 mm, "
        "EI_max / EI_min = 1600, loaded at the centroid of its free end."
    )
    return res
