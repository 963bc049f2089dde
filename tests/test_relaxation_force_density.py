"""The start state of the implicit relaxation: the force-density shape."""

import numpy as np
import pytest

from shellform import ModelError, Structure, build_system
from shellform.solvers.relaxation import force_density_start, relax

from test_relaxation import chain, small_net


def test_force_density_chain_is_a_parabola_in_balance_with_its_stiffness():
    n, EA, scale = 20, 1e3, 0.1
    system = chain(n, EA=EA)
    q = force_density_start(system, stiffness_scale=scale)
    x = q.reshape(-1, 3)
    # one force density under equal nodal loads: x stays evenly spaced, z is a parabola
    assert np.allclose(np.diff(x[:, 0]), x[1, 0] - x[0, 0])
    assert np.allclose(x[:, 1], 0.0)
    d2 = np.diff(x[:, 2], 2)
    assert np.allclose(d2, d2[0], rtol=1e-9) and d2[0] > 0
    # the force density from the balance of an inner node, c * (z_left + z_right - 2 z) = -f_z
    f = system.external_force().reshape(-1, 3)
    c = -f[1, 2] / d2[0]
    d = np.diff(x, axis=0)
    length = np.linalg.norm(d, axis=1)
    L = system.effects[0].L
    # mean strain equals the mean strain of ropes of stiffness scale * EA carrying c * l
    assert np.mean(length / L - 1) == pytest.approx(np.mean(c * length / (scale * EA)), rel=1e-5)
    assert np.all(x[[0, n]] == system.q_ref.reshape(-1, 3)[[0, n]])  # supports where they were


def test_force_density_start_refuses_a_net_it_cannot_hold():
    # two free nodes joined to each other but to no support: the Laplacian is singular
    s = Structure([[0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0]])
    s.add_ropes([[0, 1], [2, 3]], EA=1e3, slack=0.1, mass_per_length=1.0)
    s.fix([0, 1])
    s.set_gravity()
    assert force_density_start(build_system(s, check=False)) is None


@pytest.mark.parametrize("make", [lambda: chain(30, EA=1e5), lambda: small_net(n=7, boundary=True),
                                  lambda: small_net(n=6)])
def test_force_density_and_reference_starts_reach_the_same_equilibrium(make):
    system = make()
    fd = relax(system, rtol=1e-9)
    flat = relax(system, rtol=1e-9, start="reference")
    assert fd.success and flat.success, (fd.message, flat.message)
    assert fd.start == "force_density" and flat.start == "reference"
    assert np.max(np.abs(fd.q - flat.q)) < 1e-7
    given = relax(system, flat.q, rtol=1e-9)
    assert given.start == "given" and given.iterations <= 2


def test_explicit_scheme_can_start_from_the_force_density_shape():
    system = chain(10, EA=1e4)
    ref = relax(system, rtol=1e-8)
    res = relax(system, scheme="kinetic", start="force_density", rtol=1e-8)
    assert res.success and res.start == "force_density"
    assert np.max(np.abs(res.q - ref.q)) < 1e-5


def test_force_density_shape_balances_the_load_with_the_given_densities():
    from shellform.solvers.relaxation import force_density_shape

    system = small_net(n=7, boundary=True)
    rope = system.effects[0]
    rng = np.random.default_rng(5)
    density = rng.uniform(50.0, 150.0, len(rope.L))
    x = force_density_shape(system, density).reshape(-1, 3)
    # at every free node the members pull with q (x_j - x_i) against the load
    pull = density[:, None] * (x[rope.conn[:, 1]] - x[rope.conn[:, 0]])
    force = system.external_force().reshape(-1, 3).copy()
    np.add.at(force, rope.conn[:, 0], pull)
    np.add.at(force, rope.conn[:, 1], -pull)
    free = force.ravel()[system.free]
    assert np.abs(free).max() <= 1e-9 * np.abs(system.external_force()).max()
    assert np.all(x.ravel()[system.constrained] == system.q_ref[system.constrained])
    with pytest.raises(ModelError, match="finite, non-negative force densities"):
        force_density_shape(system, -density)
