"""Starts from a coarser hanging net: its force densities and shape carried over; the default of large nets."""

import time
from types import SimpleNamespace

import numpy as np
import pytest

from shellform import ModelError
from shellform.geometry import rectangle_grid
from shellform.mra import form_find, hanging_net
from shellform.mra.coarsen import coarsened_net, structured_lines
from shellform.mra.start import (MAX_DEEPENING, coarse_force_density_start, coarse_shape_start, interpolated_shape,
                                 transferred_force_densities)

SIX_POINTS = {"positions": [[0, 0], [-1, 0], [0, -1], [-1, -1], [0, 2], [-1, 2]]}


def _assert_linear_field_carries_over(coarse_net, net):
    """A force-density field linear in the structured coordinates is interpolated exactly inside the coarse lattice."""
    def field(uv, fam):  # one per family
        return (100.0 + 40.0 * uv[:, 0] - 25.0 * uv[:, 1]) * (1.0 if fam == 0 else 1.5)

    def midpoints(n):
        u, v = structured_lines(n)
        uv = np.column_stack([u[n.grid.ij[:, 0]], v[n.grid.ij[:, 1]]])
        return 0.5 * (uv[n.rope_edges[:, 0]] + uv[n.rope_edges[:, 1]])

    cm = midpoints(coarse_net)
    density = np.where(coarse_net.family == 0, field(cm, 0), field(cm, 1))
    length = np.full(len(density), 3.0)
    coarse = SimpleNamespace(net=coarse_net, tension=density * length, length=length)
    q = transferred_force_densities(coarse, net)
    ratio = net.total_weight() / coarse_net.total_weight()
    fm = midpoints(net)
    for fam in (0, 1):
        sel = net.family == fam
        lo, hi = cm[coarse_net.family == fam].min(axis=0), cm[coarse_net.family == fam].max(axis=0)
        inside = sel & np.all((fm >= lo - 1e-12) & (fm <= hi + 1e-12), axis=1)
        assert inside.sum() > 10
        assert q[inside] == pytest.approx(ratio * field(fm[inside], fam), rel=1e-12)
        # beyond it, the edge values of the lattice
        assert np.all(q[sel] >= ratio * field(fm[sel], fam).min() * 0.99)


def test_force_densities_carry_over_from_a_coarser_net():
    coarse_net = hanging_net(rectangle_grid(8.0, 4.0, 4, 2), SIX_POINTS, slack=0.05)
    net = hanging_net(rectangle_grid(8.0, 4.0, 12, 6), SIX_POINTS, slack=0.05)
    # a net on its own coarser grid weighs less: the densities scale with the weights
    assert net.total_weight() / coarse_net.total_weight() > 2
    _assert_linear_field_carries_over(coarse_net, net)


def test_force_densities_carry_over_from_an_uneven_lattice():
    # corners and one inner point, so that no coarse rope joins two supports (and goes missing)
    net = hanging_net(rectangle_grid(12.0, 6.0, 12, 6), {"groups": ["corners"], "positions": [[4, 2]]}, slack=0.05)
    coarse_net = coarsened_net(net, 3)
    u, v = structured_lines(coarse_net)  # not evenly spaced
    np.testing.assert_allclose(u * 12, [0, 3, 4, 6, 9, 12])
    np.testing.assert_allclose(v * 6, [0, 2, 3, 6])
    assert len(coarse_net.rope_edges) == len(coarse_net.grid.edges)
    assert coarse_net.total_weight() == pytest.approx(net.total_weight())
    _assert_linear_field_carries_over(coarse_net, net)


def test_coarse_net_start_reaches_the_default_shape():
    frames = [{"from": [0, 0], "to": [0, 12]}, {"from": [24, 0], "to": [24, 12]}]
    net = hanging_net(rectangle_grid(12.0, 6.0, 24, 12), {"frames": frames}, slack=0.05)
    default = form_find(net, rtol=1e-9)
    coarse = form_find(net, start="coarse_net", rtol=1e-9)
    assert coarse.converged and coarse.relaxation.start == "coarse_net"
    assert np.abs(coarse.positions - default.positions).max() < 1e-6
    assert form_find(net, default.positions.ravel(), start="coarse_net").relaxation.start == "given"
    with pytest.raises(ModelError, match="unknown start 'coarse'"):
        form_find(net, start="coarse")


def test_large_nets_start_from_their_coarse_net_by_default(monkeypatch):
    from shellform.mra import formfind

    net = hanging_net(rectangle_grid(12.0, 12.0, 12, 12), {"groups": ["boundary"]}, slack=0.05)
    assert form_find(net).relaxation.start == "force_density"
    monkeypatch.setattr(formfind, "COARSE_START_NODES", net.structure.n_nodes)
    assert form_find(net).relaxation.start == "coarse_net"
    assert form_find(net, start="force_density").relaxation.start == "force_density"
    assert form_find(net, scheme="kinetic", max_iterations=10).relaxation.start == "reference"
    # a net too small to coarsen starts from the force-density shape, unless the coarse net was asked for
    small = hanging_net(rectangle_grid(3.0, 3.0, 3, 3), {"groups": ["boundary"]}, slack=0.05)
    monkeypatch.setattr(formfind, "COARSE_START_NODES", 1)
    assert form_find(small).relaxation.start == "force_density"
    with pytest.raises(ModelError, match="coarse net"):
        form_find(small, start="coarse_net")


def test_lowered_force_densities_hang_the_start_deeper_in_proportion():
    net = hanging_net(rectangle_grid(12.0, 12.0, 12, 12), {"groups": ["boundary"]}, slack=0.05)
    coarse = form_find(coarsened_net(net, 3))
    as_is = coarse_force_density_start(coarse, net, 1.0).reshape(-1, 3)
    lowered = coarse_force_density_start(coarse, net).reshape(-1, 3)
    # under vertical loads the planform positions depend only on the density ratios,
    # the sag below the (level) rim on their level
    np.testing.assert_allclose(lowered[:, :2], as_is[:, :2], atol=1e-12)
    np.testing.assert_allclose(lowered[:, 2], as_is[:, 2] / 0.9, rtol=1e-10, atol=1e-12)
    assert as_is[:, 2].min() < -0.1
    with pytest.raises(ModelError, match="density_scale must be positive"):
        coarse_force_density_start(coarse, net, 0.0)


def test_interpolated_shape_passes_through_the_coarse_nodes_and_is_linear_along_kept_lines():
    # an uneven lattice: the suspension points keep the line j = 2
    net = hanging_net(rectangle_grid(12.0, 6.0, 12, 6), SIX_POINTS, slack=0.05)
    coarse = form_find(coarsened_net(net, 3))
    x = interpolated_shape(coarse, net)
    source = coarse.net.info["source"]
    np.testing.assert_allclose(x[source], coarse.positions, atol=1e-12)
    # on the kept line j = 2, a third of the way from the coarse node at i = 3 to the one at i = 6
    ij = net.grid.ij
    at = lambda i, j: int(np.flatnonzero((ij[:, 0] == i) & (ij[:, 1] == j))[0])  # noqa: E731
    a, b = (int(np.flatnonzero(source == at(i, 2))[0]) for i in (3, 6))
    np.testing.assert_allclose(x[at(4, 2)], (2 * coarse.positions[a] + coarse.positions[b]) / 3, atol=1e-12)


def test_interpolated_shape_leaves_out_lattice_points_without_a_coarse_node():
    def lattice_net(lines, ij):
        grid = SimpleNamespace(shape=(len(lines), len(lines)), ij=np.array(ij))
        return SimpleNamespace(grid=grid, info={"lattice": (np.array(lines), np.array(lines))})

    p = np.array([[0.0, 0.0, -1.0], [2.0, 0.0, -3.0], [0.0, 2.0, -5.0]])
    coarse = SimpleNamespace(net=lattice_net([0.0, 1.0], [[0, 0], [1, 0], [0, 1]]), positions=p)  # (1, 1) missing
    fine = lattice_net([0.0, 0.5, 1.0], [[0, 0], [1, 0], [1, 1], [0, 1]])
    np.testing.assert_allclose(interpolated_shape(coarse, fine), [p[0], (p[0] + p[1]) / 2, p.mean(axis=0),
                                                                  (p[0] + p[2]) / 2], atol=1e-12)
    # a node of the net right at the missing point gets nothing
    assert interpolated_shape(coarse, lattice_net([0.0, 0.5, 1.0], [[0, 0], [2, 2]])) is None


def test_coarse_shape_start_hangs_the_coarse_shape_deeper_to_the_median_strain():
    net = hanging_net(rectangle_grid(12.0, 12.0, 12, 12), {"groups": ["boundary"]}, slack=0.05)
    coarse = form_find(coarsened_net(net, 3))
    x = interpolated_shape(coarse, net)
    e, rest = net.rope_edges, net.rest_length

    def median_strain(y):
        return np.median(np.linalg.norm(y[e[:, 1]] - y[e[:, 0]], axis=1) / rest - 1)

    assert median_strain(x) < 1e-4  # as interpolated, the ropes across the coarse cells are short
    start = coarse_shape_start(coarse, net, 1e-3).reshape(-1, 3)
    assert median_strain(start) == pytest.approx(1e-3, rel=1e-6)
    # only the sag grows (the load is vertical, the rim level and held)
    np.testing.assert_allclose(start[:, :2], x[:, :2], atol=1e-12)
    np.testing.assert_array_equal(start[net.supports], net.structure.nodes[net.supports])
    ratio = start[:, 2][x[:, 2] < -0.1] / x[:, 2][x[:, 2] < -0.1]
    assert np.ptp(ratio) < 1e-12 and 1.0 < ratio[0] < 1.0 + MAX_DEEPENING
    # a strain the ropes cannot reach deepens by the most allowed; one they have already, not at all
    np.testing.assert_allclose(coarse_shape_start(coarse, net, 0.5).reshape(-1, 3)[:, 2],
                               (1 + MAX_DEEPENING) * x[:, 2], atol=1e-12)
    deep = SimpleNamespace(net=coarse.net, positions=coarse.positions * [1.0, 1.0, 1.5])
    x_deep = interpolated_shape(deep, net)
    assert median_strain(x_deep) > 1e-3
    np.testing.assert_allclose(coarse_shape_start(deep, net, 1e-3).reshape(-1, 3), x_deep, atol=1e-12)
    for bad in (np.nan, -1e-3):
        with pytest.raises(ModelError, match="median_strain must be a finite number"):
            coarse_shape_start(coarse, net, bad)


def test_coarse_nets_report_their_steps_as_text(monkeypatch):
    from shellform.mra import formfind

    net = hanging_net(rectangle_grid(12.0, 12.0, 12, 12), {"groups": ["boundary"]}, slack=0.05)
    monkeypatch.setattr(formfind, "COARSE_START_NODES", net.structure.n_nodes)
    lines, states = [], []
    res = form_find(net, progress=lines.append, callback=lambda info: states.append(info.q.size))
    coarse_nodes = coarsened_net(net, 3).structure.n_nodes
    assert res.converged and res.relaxation.start == "coarse_net"
    steps = [s for s in lines if "iteration" in s]
    assert steps and all(f"coarse net of {coarse_nodes:,} nodes" in s for s in steps)
    assert any(s.startswith(f"  coarse net of {coarse_nodes:,} nodes: at rest after") for s in lines)
    # the callback sees the full net's states only
    assert states and set(states) == {3 * net.structure.n_nodes}


@pytest.mark.filterwarnings("ignore::shellform.mra.formfind.OverstretchWarning")  # stopped far from rest
def test_the_wall_time_limit_covers_the_coarse_net(monkeypatch):
    from shellform.mra import formfind, start

    net = hanging_net(rectangle_grid(12.0, 12.0, 12, 12), {"groups": ["boundary"]}, slack=0.05)
    monkeypatch.setattr(formfind, "COARSE_START_NODES", net.structure.n_nodes)
    hang_coarse = start.coarse_net_start

    def slow_coarse_start(*args, **kwargs):
        out = hang_coarse(*args, **kwargs)
        time.sleep(0.3)
        return out

    monkeypatch.setattr(start, "coarse_net_start", slow_coarse_start)
    res = form_find(net, max_wall_time=0.2)
    assert not res.converged
    assert "not converged within the wall-time limit of 0.2 s" in res.relaxation.message
    assert res.relaxation.iterations <= 1 and res.relaxation.wall_time_s > 0.3
