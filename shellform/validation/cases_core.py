"""Validation cases of the core: hanging chain and von Mises truss."""

from __future__ import annotations

import numpy as np
from scipy.optimize import brentq

from ..assembly import build_system
from ..io.table import CurveStyle, plot_curve
from ..model import Structure
from ..solvers import solve_static
from .reference import CATENARY_SOURCE, CATENARY_TOLERANCE, VON_MISES_SOURCE
from .report import CaseResult, Check


def hanging_chain(span: float, length: float, n: int, w: float = 1.0, EA: float = 1.0e8):
    """A chain of ``n`` equal, nearly inextensible ropes between two supports,
    with a parabolic start 1 % longer than the chain (every rope taut)."""
    s = Structure(np.column_stack([np.linspace(0, span, n + 1), np.zeros(n + 1), np.zeros(n + 1)]))
    s.add_ropes(np.column_stack([np.arange(n), np.arange(1, n + 1)]), EA=EA, rest_length=length / n,
                mass_per_length=w / 9.81)
    s.fix([0, n])
    s.set_gravity()
    xf = np.linspace(0, span, 20 * n + 1)

    def parabola(f):
        z = -4 * f * xf * (span - xf) / span**2
        return z, np.concatenate([[0], np.cumsum(np.hypot(np.diff(xf), np.diff(z)))])

    f0 = brentq(lambda f: parabola(f)[1][-1] - 1.01 * length, 1e-6 * span, span)
    z, arc = parabola(f0)
    st = np.linspace(0, arc[-1], n + 1)
    q0 = np.column_stack([np.interp(st, arc, xf), np.zeros(n + 1), np.interp(st, arc, z)]).ravel()
    return s, q0


def catenary_sag(span: float, length: float) -> float:
    a = brentq(lambda a: 2 * a * np.sinh(span / (2 * a)) - length, 1e-3 * span, 1e3 * span)
    return a * (np.cosh(span / (2 * a)) - 1)


def case_catenary(out) -> CaseResult:
    span, length = 10.0, 12.0
    exact = catenary_sag(span, length)
    res = CaseResult("catenary", "hanging chain against the analytic catenary (static Newton)")
    rows = []
    for n in (25, 50, 100, 200, 400):
        s, q0 = hanging_chain(span, length, n)
        r = solve_static(build_system(s), q0=q0)
        sag = -r.q.reshape(-1, 3)[:, 2].min()
        rows.append((n, sag, r.iterations, r.wall_time_s))
        res.checks.append(Check(f"sag, {n} segments [m]", sag, exact, CATENARY_TOLERANCE, source=CATENARY_SOURCE))
    res.notes = "Span 10 m, chain 12 m, EA/w = 1e8 m. Sag error falls as 1/n^2: " + ", ".join(
        f"n={n}: {abs(sag - exact) / exact:.2e} ({it} it., {t:.3f} s)" for n, sag, it, t in rows)
    return res


def case_von_mises(out) -> CaseResult:
    from ..solvers.continuation import trace_path

    L, H, EA = 1.0, 0.2, 1.0e4
    alpha = np.arctan(H / L)
    q_cr = np.arccos(np.cos(alpha) ** (1 / 3))
    p_cr = 2 * EA * np.sin(q_cr) ** 3
    s = Structure([[-L, 0, 0], [0, 0, H], [L, 0, 0]])
    s.add_bars([[0, 1], [1, 2]], EA=EA)
    s.fix([0, 2])
    s.fix([1], "y")
    s.add_load([1], [0, 0, -1.0])
    system = build_system(s)
    path = trace_path(system, control="load", parameter_bounds=(-2 * p_cr, 2 * p_cr), max_displacement=2.5 * H,
                      initial_increment=0.1 * p_cr, monitors={"w": 5})
    limits = [e for e in path.events if e.kind == "limit"]
    res = CaseResult("von_mises", "two-bar truss traced through its limit points (arc-length, load control)")
    res.checks.append(Check("first limit load [N]", limits[0].load if limits else np.nan, p_cr, 5e-3,
                            source=VON_MISES_SOURCE))
    res.checks.append(Check("second limit load [N]", limits[1].load if len(limits) > 1 else np.nan, -p_cr, 5e-3,
                            source=VON_MISES_SOURCE))
    # every traced point on the analytic curve P(theta) = 2 EA sin(theta) (1 - cos(alpha) / cos(theta))
    theta = np.arctan((H + path["w"]) / L)
    analytic = 2 * EA * np.sin(theta) * (1 - np.cos(alpha) / np.cos(theta))
    worst = float(np.max(np.abs(path["lam"] - analytic)) / p_cr)
    res.checks.append(Check("largest deviation from the analytic curve / P_cr", worst, 0.0, 1e-6, relative=False,
                            source=VON_MISES_SOURCE))
    fig = out / "von_mises.png"
    plot_curve(fig, -path["w"], path["lam"], "apex deflection [m]", "apex load [N]",
               "von Mises truss: traced points and analytic curve",
               CurveStyle(marks=[(-(e.q[5] - H), e.load, "limit") for e in limits], stable=path["n_negative"] == 0))
    res.figures.append(fig.name)
    return res
