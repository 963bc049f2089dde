"""Continuum limit: equal-force-density nets converge to the small-slope membrane."""

import numpy as np
import pytest

from shellform.assembly import build_system
from shellform.mra.membrane import force_density_net, force_density_solve, membrane_centre_deflection
from shellform.solvers.relaxation import relax

SQUARE_COEFFICIENT = 0.0736714  # small-slope membrane on a square, w_max = c p a^2 / N (reference.MEMBRANE_SQUARE_COEFFICIENT)


@pytest.fixture(scope="module")
def continuum():
    return membrane_centre_deflection(refine=5)


def test_fem_membrane_matches_the_analytic_coefficient(continuum):
    assert continuum == pytest.approx(SQUARE_COEFFICIENT, rel=2e-6)


def test_nets_converge_to_the_membrane_at_second_order(continuum):
    errors = []
    for n in (4, 8, 16, 32):
        s, grid, centre = force_density_net(n)
        system = build_system(s)
        res = relax(system, scheme="implicit", rtol=1e-10)
        assert res.success, res.message
        w = -res.q[3 * centre + 2]
        # the MRA relaxation solves exactly the linear force-density problem (force density q (1 - 1e-9))
        w_fd = force_density_solve(n)[n // 2 - 1, n // 2 - 1]
        assert w == pytest.approx(w_fd, rel=1e-8)
        # in-plane positions stay on the planform grid (horizontal equilibrium of equal force densities)
        assert np.max(np.abs(res.q.reshape(-1, 3)[:, :2] - grid.nodes[:, :2])) < 1e-10
        errors.append(abs(w - continuum) / continuum)
    ratios = np.array(errors[:-1]) / np.array(errors[1:])
    assert np.all((ratios > 3.6) & (ratios < 4.4))  # error ~ h^2
    assert errors[-1] < 1e-3


def test_explicit_relaxation_of_the_membrane_net():
    s, grid, centre = force_density_net(6)
    system = build_system(s)
    fast = relax(system, scheme="implicit", rtol=1e-9)
    slow = relax(system, scheme="rk4", rtol=1e-9)
    assert slow.success
    assert np.max(np.abs(slow.q - fast.q)) < 1e-8
