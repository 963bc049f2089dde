"""The pre-stressed hemispherical gridshell: rod network on the Chebyshev net and its two construction routes."""

import numpy as np
import pytest

from shellform.errors import ModelError
from shellform.gridshell.hemisphere import (
    HemisphereSpec,
    build_hemisphere,
    compare_shapes,
    prestress_by_paths,
    prestress_on_net,
)

R = 0.0764 / 2  # the gridshell paper's hemisphere: 2R = 7.64 cm
DL = 4.0e-3  # coarse Voronoi length for the default suite


@pytest.fixture(scope="module")
def on_net():
    model = build_hemisphere(HemisphereSpec(5, voronoi_length=DL))
    return model, prestress_on_net(model)


def test_joints_are_rod_nodes_at_the_net_points(on_net):
    model, _ = on_net
    net = model.net
    assert len(model.joint_nodes) == len(net.joints) == 21  # the four corner crossings lie below the equator
    for (ku, kv), (a, b) in zip(model.joint_keys, model.joint_nodes):
        assert a != b  # penalty joints: one node on each rod
        p = next(j.position for j in net.joints if (j.u_index, j.v_index) == (ku, kv))
        assert np.allclose(model.sphere_nodes[a], p, atol=1e-12)
        assert np.allclose(model.sphere_nodes[b], p, atol=1e-12)
        # on the u rod the joint sits at arc length v_index h, on the v rod at u_index h
        ru, rv = model.rod_index("u", ku), model.rod_index("v", kv)
        su = model.rod_stations[ru][model.rod_nodes[ru] == a][0]
        sv = model.rod_stations[rv][model.rod_nodes[rv] == b][0]
        assert su == pytest.approx(kv * net.spacing, abs=1e-12)
        assert sv == pytest.approx(ku * net.spacing, abs=1e-12)


def test_rest_lengths_are_the_planar_rods(on_net):
    model, _ = on_net
    h = model.net.spacing
    net = model.network
    for k, rod in enumerate(model.net.rods):
        r = net.rods[k]
        rest = net.rest_length[r.edges]
        assert rest.sum() == pytest.approx(rod.length, rel=1e-12)
        # every inter-joint segment is cut into round(h / dl) equal edges
        assert np.isclose(rest, h / round(h / DL)).sum() >= len(rest) - 2 * int(np.ceil(h / DL))
    assert np.all(net.natural_curvature == 0.0)  # straight when unstressed


def test_apex_and_its_neighbours(on_net):
    model, _ = on_net
    apex = model.apex_nodes
    assert len(apex) == 2 and np.allclose(model.sphere_nodes[apex], [0, 0, R], atol=1e-12)
    nb = model.apex_neighbours()
    assert len(nb) == 4
    d = np.linalg.norm(model.sphere_nodes[nb] - [0, 0, R], axis=1)
    assert np.allclose(d, d[0], rtol=1e-6) and d[0] < 1.01 * DL


def test_relaxed_net_stays_close_to_the_hemisphere(on_net):
    model, pre = on_net
    assert pre.success, pre.message
    x = model.positions(pre.q)
    # pinned ends do not move, the apex sinks a little under the pre-stress
    assert np.allclose(x[model.end_nodes.ravel()], model.equator_ends.reshape(-1, 3), atol=1e-12)
    assert 0.99 * R < x[model.apex_nodes, 2].mean() < R
    assert np.max(np.abs(np.linalg.norm(x, axis=1) - R)) < 0.03 * R
    # the rods are bent: the pre-stress is real
    assert pre.system.energy(pre.q) > 0


def test_both_construction_routes_give_the_same_shape(on_net):
    model, pre = on_net
    flat = build_hemisphere(HemisphereSpec(5, voronoi_length=DL, configuration="plane"))
    start = flat.positions(flat.structure.reference_state())
    assert np.allclose(start[:, 2], flat.params["bump"] * R * (1 - (np.linalg.norm(start[:, :2], axis=1)
                                                                      / np.linalg.norm(start[:, :2], axis=1).max()) ** 2))
    built = prestress_by_paths(flat, n_steps=20)
    assert built.success, built.message
    cmp = compare_shapes(model, built.q, pre.q)
    assert cmp["max_node_distance_over_R"] < 1e-6


def test_bad_parameters_are_named():
    with pytest.raises(ModelError, match="joints"):
        build_hemisphere(HemisphereSpec(5, joints="glued"))
    with pytest.raises(ModelError, match="voronoi_length"):
        build_hemisphere(HemisphereSpec(5, voronoi_length=0.1))
    with pytest.raises(ModelError, match="odd"):
        build_hemisphere(HemisphereSpec(4))
    with pytest.raises(ModelError, match="configuration"):
        build_hemisphere(HemisphereSpec(5, configuration="cylinder"))
