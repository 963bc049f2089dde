"""Boundary conditions of rods: clamps, pins with twist fixed or free, supports moved along paths."""

import numpy as np
import pytest

from shellform.errors import ModelError
from shellform.model import Structure
from shellform.rods import NodePath, RodNetwork, RodSection, build_rod_system
from shellform.rods.statics import solve_incremental


def straight(n=10, L=1.0):
    x = np.linspace(0, L, n + 1)
    s = Structure(np.stack([x, 0 * x, 0 * x], axis=1))
    net = RodNetwork(s)
    rod = net.add_rod(np.arange(n + 1), RodSection(EA=1e3, EI=1.0, GJ=0.8))
    return s, net, rod


def test_clamp_and_pin_constrain_the_right_dofs():
    s, net, rod = straight(n=4)
    net.clamp(rod, "start")
    net.pin(rod, "end", twist="free")
    c = s.constrained_mask
    assert c[:6].all() and not c[6:12].any() and c[12:15].all()
    assert c[rod.twist_dofs[0]] and not c[rod.twist_dofs[1:]].any()
    net.pin(rod, "end", twist="fixed")
    assert s.constrained_mask[rod.twist_dofs[-1]]
    with pytest.raises(ModelError, match="twist"):
        net.pin(rod, "start", twist="maybe")
    with pytest.raises(ModelError, match="end"):
        net.clamp(rod, "middle")


def test_straight_waypoint_path_matches_a_linear_prescription():
    """Moving the end along straight waypoints equals Structure.prescribe with the same motion."""
    d = np.array([-0.3, 0.05, 0.02])
    s1, net1, r1 = straight()
    net1.pin(r1, "start")
    net1.fix_twist(r1, "end")
    s1.prescribe([s1.n_nodes - 1], d)
    a = solve_incremental(build_rod_system(net1), mu=1.0, n_steps=8)
    s2, net2, r2 = straight()
    net2.pin(r2, "start")
    net2.fix_twist(r2, "end")
    end = s2.n_nodes - 1
    path = NodePath.waypoints(s2, [end], [0.0, 1.0], [s2.nodes[[end]], s2.nodes[[end]] + d])
    b = solve_incremental(build_rod_system(net2), paths=[path], n_steps=8)
    assert a.success and b.success, (a.message, b.message)
    assert np.allclose(b.q[3 * end : 3 * end + 3], s2.nodes[end] + d, atol=1e-14)
    assert np.allclose(a.q, b.q, atol=1e-9)


def test_static_steps_along_a_curved_path_rotate_a_rod_rigidly():
    """The far end goes a quarter turn about z and then a quarter turn about x, in static steps
    with the twist of both end edges held: a rigid motion, so no energy may build up."""
    n, L = 10, 1.0
    s, net, rod = straight(n, L)
    net.pin(rod, "start", twist="fixed")
    net.fix_twist(rod, "end")

    def tip(t):
        a = 0.5 * np.pi * min(t, 1.0)
        b = 0.5 * np.pi * min(max(t - 1.0, 0.0), 1.0)
        return L * np.array([[np.cos(a), np.sin(a) * np.cos(b), np.sin(a) * np.sin(b)]])

    path = NodePath.curve(s, [n], tip)
    system = build_rod_system(net)
    res = solve_incremental(system, paths=[path], t_end=2.0, n_steps=20)
    assert res.success, res.message
    X = res.q[: 3 * s.n_nodes].reshape(-1, 3)
    assert np.allclose(X, np.outer(np.linspace(0, L, n + 1), [0.0, 0.0, 1.0]), atol=1e-9)
    assert system.energy(res.q) == pytest.approx(0.0, abs=1e-14)


def test_path_with_wrong_size_is_reported():
    s, net, rod = straight(n=3)
    path = NodePath.curve(s, [3], lambda t: np.zeros((2, 3)))
    with pytest.raises(ModelError, match="expected 3 values"):
        path(0.0)
