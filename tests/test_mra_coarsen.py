"""Coarsened nets: the kept grid lines, their load, slack and supports."""

import numpy as np
import pytest
from test_mra_start import SIX_POINTS

from shellform import ModelError
from shellform.geometry import rectangle_grid
from shellform.mra import hanging_net
from shellform.mra.coarsen import coarsened_net, structured_lines


def test_lattice_keeps_the_crossings_of_the_chosen_lines():
    fine = rectangle_grid(6.0, 4.0, 6, 4)
    grid, source = fine.lattice([0, 3, 6], [0, 1, 4])
    assert grid.shape == (3, 3) and grid.n_nodes == 9
    np.testing.assert_array_equal(fine.ij[source], [[i, j] for i in (0, 3, 6) for j in (0, 1, 4)])
    np.testing.assert_allclose(grid.nodes, fine.nodes[source])
    # 2 x 3 edges along i, 3 x 2 along j, each joining neighbouring crossings
    assert len(grid.edges) == 12
    steps = np.abs(grid.ij[grid.edges[:, 1]] - grid.ij[grid.edges[:, 0]]).sum(axis=1)
    assert np.all(steps == 1)
    assert len(grid.boundary) == 8 and len(grid.quads) == 4
    np.testing.assert_array_equal(source[grid.group("corners")], fine.group("corners"))
    for bad in ([0, 3], [1, 3, 6], [0, 3, 3, 6]):
        with pytest.raises(ModelError, match="i lines must increase from 0 to 6"):
            fine.lattice(bad, [0, 4])


def test_coarsened_net_keeps_the_load_the_slack_and_the_supports():
    net = hanging_net(rectangle_grid(12.0, 6.0, 12, 6), SIX_POINTS, slack=0.05, EA=2.0e4,
                      node_mass=np.linspace(0.0, 3.0, 13 * 7), loads=np.tile([0.0, 0.0, -5.0], (13 * 7, 1)))
    coarse = coarsened_net(net, 3)
    # every third line, and the line j = 2 of two suspension points
    u, v = structured_lines(coarse)
    np.testing.assert_allclose(u * 12, [0, 3, 6, 9, 12])
    np.testing.assert_allclose(v * 6, [0, 2, 3, 6])
    # the same load: weight of every mass plus the nodal loads
    assert coarse.total_weight() == pytest.approx(net.total_weight(), rel=1e-12)
    # the same suspension points, where they were
    src = coarse.info["source"]
    np.testing.assert_array_equal(np.sort(src[coarse.supports]), np.sort(net.supports))
    # a chain of straight fine ropes keeps their slack
    span = np.linalg.norm(np.diff(coarse.grid.nodes[coarse.rope_edges], axis=1)[:, 0], axis=1)
    np.testing.assert_allclose(coarse.rest_length, 1.05 * span, rtol=1e-12)
    # stiffness of the chain in series (that of one fine rope) times the fine lines it carries:
    # j lines 0, 2, 3, 6 have gaps 2, 1, 3; the i lines are three apart
    carried = {0: 2.0, 2: 1.5, 3: 2.0, 6: 3.0}
    j_of = np.rint(v[coarse.grid.ij[coarse.rope_edges[:, 0], 1]] * 6).astype(int)
    expected = np.where(coarse.family == 0, [carried[j] for j in j_of], 3.0) * 2.0e4
    np.testing.assert_allclose(coarse.EA, expected, rtol=1e-12)


def test_coarsened_net_keeps_lifted_frames_and_their_lines():
    frames = [{"from": [0, 0], "to": [0, 8]}, {"from": [16, 0], "to": [16, 8]}, {"from": [5, 0], "to": [5, 8], "rise": 1.0}]
    net = hanging_net(rectangle_grid(8.0, 4.0, 16, 8), {"frames": frames}, slack=0.05)
    coarse = coarsened_net(net, 4)
    u, _ = structured_lines(coarse)
    np.testing.assert_allclose(u * 16, [0, 4, 5, 8, 12, 16])
    src = coarse.info["source"]
    # the arch stays lifted, and the ropes along it stay out of the net
    np.testing.assert_allclose(coarse.structure.nodes, net.structure.nodes[src])
    assert coarse.structure.nodes[:, 2].max() == pytest.approx(1.0)
    assert set(map(tuple, src[coarse.rope_edges].tolist())).isdisjoint(map(tuple, net.info["held_ropes"].tolist()))
    assert not np.any(np.all(np.isin(src[coarse.rope_edges], net.supports), axis=1))


def test_coarsening_is_refused_where_it_would_not_coarsen():
    net = hanging_net(rectangle_grid(4.0, 4.0, 4, 4), {"groups": ["boundary"]}, slack=0.05)
    with pytest.raises(ModelError, match="at least 2"):
        coarsened_net(net, 1)
    points = {"positions": [[i, j] for i in range(5) for j in range(5) if (i + j) % 2 == 0]}
    scattered = hanging_net(rectangle_grid(4.0, 4.0, 4, 4), points, slack=0.05)
    with pytest.raises(ModelError, match="would not be coarse"):
        coarsened_net(scattered, 3)


def test_rope_stiffness_per_grid_edge_follows_the_grid_order():
    grid = rectangle_grid(3.0, 2.0, 3, 2)
    EA = 1000.0 + np.arange(len(grid.edges))
    net = hanging_net(grid, {"groups": ["south", "north"]}, slack=0.05, EA=EA)
    index = {tuple(e): k for k, e in enumerate(grid.edges.tolist())}
    np.testing.assert_array_equal(net.EA, EA[[index[tuple(e)] for e in net.rope_edges.tolist()]])
    with pytest.raises(ModelError, match="one per grid edge"):
        hanging_net(grid, {"groups": ["south", "north"]}, slack=0.05, EA=EA[:-1])
