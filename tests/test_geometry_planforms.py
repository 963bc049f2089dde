"""gmsh planforms of any shape: polygons with holes, B-spline boundaries, surface files; named node sets."""

import numpy as np
import pytest

from shellform.errors import ModelError
from shellform.geometry import QuadGrid
from shellform.geometry.meshnet import MeshNet, mesh_net
from shellform.geometry.planforms import BoundaryCurve, curve_planform, polygon_planform, surface_planform
from shellform.geometry.selection import nearest_nodes, nodes_in_box, nodes_on_polyline

L_SHAPE = [(0, 0), (2, 0), (2, 1), (1, 1), (1, 2), (0, 2)]


@pytest.mark.parametrize("elements, cell", [("quads", "quad"), ("triangles", "triangle")])
def test_polygon_with_re_entrant_corner_is_meshed_at_the_edge_length(elements, cell):
    net = polygon_planform(L_SHAPE, edge_length=0.1, elements=elements)
    assert isinstance(net, MeshNet) and not net.structured
    assert set(net.faces) == {cell}
    lengths = np.linalg.norm(net.nodes[net.edges[:, 1]] - net.nodes[net.edges[:, 0]], axis=1)
    assert 0.07 < np.median(lengths) < 0.13
    # the six corners of the L, and the area of the faces is the L's (3 m^2)
    corners = net.nodes[net.group("corners"), :2]
    assert sorted(map(tuple, np.round(corners, 9))) == sorted(map(tuple, np.array(L_SHAPE, float)))
    area = sum(_area(net.nodes, f) for f in net.faces.values())
    assert area == pytest.approx(3.0, rel=1e-12)
    # side 3 runs from (1, 1) to (1, 2)
    side = net.nodes[net.group("side_3")]
    assert np.allclose(side[:, 0], 1.0) and side[:, 1].min() == pytest.approx(1.0)


def _area(nodes, faces):
    p = nodes[faces]
    a = 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1).sum()
    if faces.shape[1] == 4:
        a += 0.5 * np.linalg.norm(np.cross(p[:, 2] - p[:, 0], p[:, 3] - p[:, 0]), axis=1).sum()
    return a


def test_four_cornered_polygon_of_quads_is_a_structured_grid():
    g = polygon_planform([(0, 0), (2, 0), (2, 1), (0, 1)], edge_length=0.1)
    assert isinstance(g, QuadGrid) and g.shape == (21, 11)
    assert np.allclose(g.nodes[g.group("ne")], [[2, 1, 0]])


def test_polygon_with_a_hole_names_the_hole():
    net = polygon_planform([(0, 0), (3, 0), (3, 3), (0, 3)], [[(1, 1), (2, 1), (2, 2), (1, 2)]], edge_length=0.2)
    hole = net.nodes[net.group("hole_1")]
    assert np.all(np.abs(np.maximum(np.abs(hole[:, 0] - 1.5), np.abs(hole[:, 1] - 1.5)) - 0.5) < 1e-12)
    assert set(net.group("hole_1")) <= set(net.boundary)
    assert _area(net.nodes, net.quads) + _area(net.nodes, net.triangles) == pytest.approx(8.0, rel=1e-12)


def _circle_arcs(r=1.0):
    w = np.sqrt(0.5)
    c = r * np.array([(1, 0, 0), (1, 1, 0), (0, 1, 0), (-1, 1, 0), (-1, 0, 0), (-1, -1, 0), (0, -1, 0), (1, -1, 0),
                      (1, 0, 0)], dtype=float)
    return [BoundaryCurve(c[2 * k:2 * k + 3], 2, np.array([1.0, w, 1.0])) for k in range(4)]


@pytest.mark.parametrize("elements", ["quads", "triangles"])
def test_nurbs_boundary_is_exact(elements):
    g = curve_planform([_circle_arcs()], edge_length=0.1, elements=elements)
    r = np.linalg.norm(g.nodes[g.boundary, :2], axis=1)
    assert np.allclose(r, 1.0, atol=1e-12)
    assert isinstance(g, QuadGrid) == (elements == "quads")  # four curves: transfinite


def test_curves_that_do_not_join_are_refused():
    arcs = _circle_arcs()
    arcs[1] = BoundaryCurve(arcs[1].control_points + 0.1, 2, arcs[1].weights)
    with pytest.raises(ModelError, match="must run end to end"):
        curve_planform([arcs], edge_length=0.1)


def test_step_and_iges_surfaces(tmp_path):
    import gmsh

    from shellform.geometry import gmsh_session

    with gmsh_session("write") as g:
        occ = g.model.occ
        occ.addRectangle(0, 0, 0, 3, 2)
        occ.addDisk(1.5, 1, 0, 0.5, 0.5)
        occ.cut([(2, 1)], [(2, 2)])
        occ.synchronize()
        gmsh.write(str(tmp_path / "court.step"))
        gmsh.write(str(tmp_path / "court.igs"))
    for name in ("court.step", "court.igs"):
        net = surface_planform(tmp_path / name, edge_length=0.2, elements="triangles")
        assert _area(net.nodes, net.triangles) == pytest.approx(6.0 - np.pi * 0.25, rel=2e-2)
        r = np.hypot(net.nodes[net.boundary, 0] - 1.5, net.nodes[net.boundary, 1] - 1.0)
        assert np.sum(np.abs(r - 0.5) < 1e-6) >= 10  # the rim on the circle (as the file stores it)


def test_bad_planforms_are_refused(tmp_path):
    with pytest.raises(ModelError, match="edge_length"):
        polygon_planform(L_SHAPE, edge_length=0.0)
    with pytest.raises(ModelError, match="elements"):
        polygon_planform(L_SHAPE, edge_length=0.1, elements="hexes")
    with pytest.raises(ModelError, match="at most"):
        polygon_planform(L_SHAPE, edge_length=1e-5)
    with pytest.raises(ModelError, match="coincide"):
        polygon_planform([(0, 0), (1, 0), (1, 0), (0, 1)], edge_length=0.1)
    with pytest.raises(ModelError, match="expected one of"):
        surface_planform(tmp_path / "a.obj", edge_length=0.1)


def test_mesh_net_of_cells_and_its_sets():
    pts = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [2, 0, 0]], dtype=float)
    net = mesh_net(pts, {"quad": np.array([[0, 1, 2, 3]]), "triangle": np.array([[1, 4, 2]])}, {"a": [4]})
    assert net.edges.tolist() == [[0, 1], [0, 3], [1, 2], [1, 4], [2, 3], [2, 4]]
    assert net.boundary.tolist() == [0, 1, 2, 3, 4] and net.group("a").tolist() == [4]
    assert net.boundary_edges().tolist() == [[0, 1], [0, 3], [1, 4], [2, 3], [2, 4]]
    with pytest.raises(ModelError, match="belongs to no quad"):
        mesh_net(np.vstack([pts, [[5, 5, 5]]]), {"quad": np.array([[0, 1, 2, 3]])})
    with pytest.raises(ModelError, match="no node set named 'b'"):
        net.group("b")


def test_node_selections():
    x = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [1, 1, 0]], dtype=float)
    assert nearest_nodes(x, [[1.9, 0.1, 0], [0.9, 0.8, 0]]).tolist() == [2, 3]
    assert nodes_in_box(x, [[0.5, -1, -1], [2.5, 0.5, 1]]).tolist() == [1, 2]
    assert nodes_on_polyline(x, [[0, 0, 0], [2, 0, 0]], 1e-9).tolist() == [0, 1, 2]
    assert nodes_on_polyline(x, [[0, 1, 0], [2, 1, 0]], 1e-9).tolist() == [3]


SQUARE = [[0.0, 0.0, 0.0], [20.0, 0.0, 0.0], [20.0, 20.0, 0.0], [0.0, 20.0, 0.0]]
HOLE = [[6.0, 6.0, 0.0], [14.0, 6.0, 0.0], [14.0, 14.0, 0.0], [6.0, 14.0, 0.0]]


@pytest.mark.parametrize("boundary, holes, message", [
    # the courtyard's boundary with a corner deleted: the hole now crosses it (gmsh meshed for ever)
    ([SQUARE[0], SQUARE[2], SQUARE[3]], [HOLE], "hole 1: not inside"),
    ([[0, 0, 0], [20, 20, 0], [20, 0, 0], [0, 20, 0]], [], "boundary: side 0 .* meets side 2"),  # a bow tie
    (SQUARE, [HOLE, [[10, 10, 0], [18, 10, 0], [18, 18, 0], [10, 18, 0]]], "hole 2 and planform hole 1 overlap"),
    (SQUARE, [[[8, 8, 0], [12, 8, 0], [12, 12, 0], [8, 12, 0]], HOLE], "hole 2 and planform hole 1 overlap"),
    (SQUARE, [[[6, 6, 0], [14, 6, 0], [14, 14, 1.0], [6, 14, 0]]], "off the plane"),
    ([[0, 0, 0], [10, 0, 0], [20, 0, 0]], [], "one line"),
])
def test_loops_gmsh_cannot_mesh_are_refused_before_meshing(boundary, holes, message):
    with pytest.raises(ModelError, match=message):
        polygon_planform(boundary, holes, edge_length=1.0)


def _shifted(curves, dx, scale=1.0):
    return [BoundaryCurve(c.control_points * scale + np.array([dx, 0.0, 0.0]), c.degree, c.weights) for c in curves]


@pytest.mark.parametrize("loops, message", [
    # a hole of radius 0.3 centred 0.8 from the centre of the unit circle: it crosses the boundary
    (lambda: [_circle_arcs(), _shifted(_circle_arcs(), 0.8, 0.3)], "hole 1: not inside"),
    (lambda: [_circle_arcs(), _shifted(_circle_arcs(), -0.3, 0.4), _shifted(_circle_arcs(), 0.3, 0.4)],
     "hole 2 and planform hole 1 overlap"),
    # one cubic curve whose control polygon makes it loop over itself, closed by a line
    (lambda: [[BoundaryCurve(np.array([[0, 0, 0], [3, 2, 0], [-1, 2, 0], [2, 0, 0.0]]), 3),
               BoundaryCurve(np.array([[2, 0, 0], [0, 0, 0.0]]), 1)]], "curve 0 meets curve 0"),
    (lambda: [[BoundaryCurve(c.control_points, 2, np.array([1.0, -0.5, 1.0])) for c in _circle_arcs()]],
     "weights must be 3 positive numbers"),
])
def test_curve_loops_gmsh_cannot_mesh_are_refused_before_meshing(loops, message):
    with pytest.raises(ModelError, match=message):
        curve_planform(loops(), edge_length=0.1)


def test_a_circular_courtyard_of_curves_is_meshed():
    g = curve_planform([_circle_arcs(), _shifted(_circle_arcs(), 0.2, 0.4)], edge_length=0.1)
    r = np.linalg.norm(g.nodes[g.group("hole_1"), :2] - [0.2, 0.0], axis=1)
    assert np.allclose(r, 0.4, atol=1e-12)


def test_a_corner_in_line_with_a_side_it_does_not_touch_is_no_crossing():
    # the first corner lies on the line of side 4 (x = 0), beyond its end, and side 0's box overlaps side 4's
    boundary = [(0, 0, 0), (1, -1.5, 0), (2, -3, 0), (-2, -3, 0), (0, -2, 0), (0, -1, 0), (-1, 0, 0)]
    net = polygon_planform(boundary, edge_length=0.25, elements="triangles")
    assert _area(net.nodes, net.triangles) == pytest.approx(4.5, rel=1e-12)


def test_an_edge_length_far_too_small_is_refused_by_size_not_by_overflow():
    from shellform.scene.checks import grid_shape

    with pytest.raises(ModelError, match="at most"):
        polygon_planform(SQUARE, [HOLE], edge_length=5e-301)
    ni, nj = grid_shape({"type": "polygon", "boundary": np.array(SQUARE), "edge_length": 5e-301})
    assert ni * nj > 10**20  # an upper estimate the size check refuses, not an overflow
