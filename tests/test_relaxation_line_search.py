"""The line search of a relaxation step and the changes of the potential it measures."""

import numpy as np
import pytest

from test_relaxation import small_net

from shellform.solvers.relaxation import relax


def test_energy_change_matches_the_potential_and_its_taylor_expansion():
    from shellform.solvers.relaxation import energy_change

    system = small_net(n=5, boundary=True)
    q = relax(system, scheme="implicit").q
    rng = np.random.default_rng(3)
    dq = np.zeros_like(q)
    dq[system.free] = rng.normal(size=system.free.size)
    # a finite change: the member-wise sum equals the difference of the totals
    big = 1e-2 * dq
    assert energy_change(system, q, q + big) == pytest.approx(system.energy(q + big) - system.energy(q), rel=1e-9)
    # a tiny change: the difference of totals is round-off, the member-wise sum follows
    # the second-order Taylor expansion g.dq + dq.K.dq / 2
    small = 1e-9 * dq
    g = system.residual(q)
    K = system.tangent(q)
    taylor = g @ small + 0.5 * small @ (K @ small)
    assert energy_change(system, q, q + small) == pytest.approx(taylor, rel=1e-5)


def test_line_search_bisects_when_the_slope_does_not_grow_along_the_step():
    # At round-off level the potential can rise at the full step while its slope there
    # equals the slope at the start; the secant then has no root and the search bisects.
    from shellform.solvers.relaxation.line_search import line_search

    calls = []

    def at(a):
        calls.append(a)
        if a == 1.0:
            return 1.0, np.zeros(3), -1.0  # a rise, with the start's slope
        return -a + a * a, np.zeros(3), -1.0 + 2.0 * a  # phi = -a + a^2 elsewhere

    alpha, dE, r = line_search(at, slope=-1.0, rnorm0=1.0, tiny=False)
    assert calls == [1.0, 0.5]
    assert alpha == 0.5 and dE == -0.25 and r is not None
