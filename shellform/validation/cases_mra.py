"""Validation cases of the multi-body rope approach: catenary, the 9 x 4 net, the membrane limit."""

from __future__ import annotations

import warnings

import numpy as np

from ..assembly import build_system
from ..geometry.grids import rectangle_grid
from ..io.table import plot_curve
from ..model import Structure
from ..mra import form_find, hanging_net
from ..mra.membrane import force_density_net, membrane_centre_deflection
from ..solvers.relaxation import relax
from .cases_core import catenary_sag
from .reference import (
    CATENARY_SOURCE,
    CATENARY_TOLERANCE,
    MEMBRANE_SOURCE,
    MEMBRANE_SQUARE_COEFFICIENT,
    MRA_SOURCE,
)
from .report import CaseResult, Check

#: the paper's Fig. 3 net: 9 x 4 ropes, the four corners and the middles of the short sides hung
NET_9X4_SUPPORTS = {"positions": [[0, 0], [-1, 0], [0, -1], [-1, -1], [0, 2], [-1, 2]]}


def slack_chain(n: int, span: float = 10.0, length: float = 12.0, w: float = 1.0, EA: float = 1.0e6) -> Structure:
    """A straight chain of ``n`` ropes between two supports whose slack makes it ``length`` long."""
    s = Structure(np.column_stack([np.linspace(0, span, n + 1), np.zeros(n + 1), np.zeros(n + 1)]))
    s.add_ropes(np.column_stack([np.arange(n), np.arange(1, n + 1)]), EA=EA, slack=length / span - 1,
                mass_per_length=w / 9.81)
    s.fix([0, n])
    s.set_gravity()
    return s


def case_mra(out) -> CaseResult:
    res = CaseResult("mra", "MRA form finding: hanging chain, the 9 x 4 net of the paper, the membrane limit")
    notes = []
    span, length, EA, w = 10.0, 12.0, 1.0e6, 1.0
    # the inextensible catenary: the ropes stretch by T / EA ~ 1e-5, far below the tolerance
    exact = catenary_sag(span, length)
    for scheme, n in (("implicit", 200), ("kinetic", 40), ("rk4", 40)):
        r = relax(build_system(slack_chain(n, span, length, w, EA)), scheme=scheme, rtol=1e-7)
        sag = -r.q.reshape(-1, 3)[:, 2].min()
        res.checks.append(Check(f"chain sag, {n} masses, scheme {scheme} [m]", sag if r.success else np.nan, exact,
                                CATENARY_TOLERANCE, source=CATENARY_SOURCE))
        notes.append(f"{scheme}, {n} masses: {r.iterations} iterations, {r.wall_time_s:.2f} s")

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        net = hanging_net(rectangle_grid(9.0, 4.0, 9, 4), NET_9X4_SUPPORTS, slack=0.05)
        hung = form_find(net)
    weight = 9.81 * float(net.structure.nodal_mass().sum())
    res.checks.append(Check("9 x 4 net: out-of-balance force / weight at rest", hung.relaxation.residual_norm / weight,
                            0.0, 1e-6, relative=False, source=MRA_SOURCE + ": equilibrium (Eqs. 6-8)"))
    res.checks.append(Check("9 x 4 net: slack ropes at rest", float(hung.slack.sum()) if hung.converged else np.nan,
                            0.0, 0.0, relative=False, source=MRA_SOURCE + ", Fig. 3: every rope taut"))
    rel = hung.relaxation.max_acceleration / 9.81
    res.checks.append(Check("9 x 4 net: largest nodal acceleration / g at rest", rel, 0.0, 1e-6, relative=False,
                            source=MRA_SOURCE + ": velocities and accelerations negligible"))
    notes.append(f"9 x 4 net: {hung.relaxation.iterations} iterations, rise {hung.rise:.3f} m"
                 f", residual {hung.relaxation.residual_norm:.2e} N against a weight of {weight:.1f} N")

    c = membrane_centre_deflection(refine=5)
    res.checks.append(Check("membrane (scikit-fem): centre deflection N / (p a^2)", c, MEMBRANE_SQUARE_COEFFICIENT,
                            1e-5, source=MEMBRANE_SOURCE))
    sizes, errors = [4, 8, 16, 32], []
    for n in sizes:
        s, grid, centre = force_density_net(n)
        r = relax(build_system(s), scheme="implicit", rtol=1e-10)
        errors.append(abs(-r.q[3 * centre + 2] - c) / c if r.success else np.nan)
    order = float(np.log2(errors[-2] / errors[-1]))
    res.checks.append(Check("equal-force-density nets to the membrane: order of convergence", order, 2.0, 0.1,
                            relative=False, source=MEMBRANE_SOURCE))
    res.checks.append(Check(f"net {sizes[-1]} x {sizes[-1]}: centre deflection vs membrane", errors[-1], 0.0,
                            1e-3, relative=False, source=MEMBRANE_SOURCE))
    fig = out / "mra_membrane_limit.png"
    plot_curve(fig, np.log2(sizes), np.log10(errors), "log2(ropes per side)",
               "log10(relative error of the centre deflection)", "hanging nets against the small-slope membrane")
    res.figures.append(fig.name)
    notes.append("membrane limit: relative errors " + ", ".join(f"n={n}: {e:.2e}" for n, e in zip(sizes, errors)))
    res.notes = "; ".join(notes) + "."
    return res
