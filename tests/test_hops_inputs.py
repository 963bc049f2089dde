"""The Hops server's geometry inputs beyond an outline: a mesh as the net, lines as the rods of a gridshell.

Driven over HTTP with rhino3dm geometry in the data trees, as Grasshopper's
Hops component sends it, and compared with the same analysis run from a scene
(the mesh written to a mesh file; the rods given as ``[nodes]`` and
``[[rods.lines]]``).
"""

from __future__ import annotations

import json

import numpy as np
import pytest

rhino3dm = pytest.importorskip("rhino3dm")

import meshio  # noqa: E402

import shellform as sf  # noqa: E402
from shellform.scene import parse_scene  # noqa: E402
from test_hops_server import lines_of, outputs, post, rectangle, request  # noqa: E402


def _error(server, body):
    status, text = post(server, body)
    assert status == 200, text
    assert "Traceback" not in text
    reply = json.loads(text)
    assert reply["values"] == [] and len(reply["errors"]) == 1, reply
    return reply["errors"][0]


# -- a mesh as the net --------------------------------------------------------------------------


def grid_net(n: int, m: int, lx: float, ly: float, z: float = 0.5, triangles: bool = True):
    """A rhino3dm mesh on an n x m grid of a horizontal rectangle (its last row of quads split into triangles),
    and its points, quads and triangles."""
    x, y = np.meshgrid(np.linspace(0.0, lx, n + 1), np.linspace(0.0, ly, m + 1), indexing="ij")
    pts = np.column_stack([x.ravel(), y.ravel(), np.full(x.size, z)])
    idx = np.arange(len(pts)).reshape(n + 1, m + 1)
    quads = np.stack([idx[:-1, :-1], idx[1:, :-1], idx[1:, 1:], idx[:-1, 1:]], axis=2).reshape(-1, 4)
    tris = np.zeros((0, 3), dtype=np.int64)
    if triangles:
        split, quads = quads[-m:], quads[:-m]
        tris = np.concatenate([split[:, [0, 1, 2]], split[:, [0, 2, 3]]])
    mesh = rhino3dm.Mesh()
    for p in pts.tolist():
        mesh.Vertices.AddPoint3d(*p)
    for f in quads.tolist() + tris.tolist():
        mesh.Faces.AddFace(*f)
    return mesh, pts, quads, tris


def mesh_file(tmp_path, pts, quads, tris) -> str:
    cells = [("quad", quads)] + ([("triangle", tris)] if len(tris) else [])
    path = tmp_path / "net.vtu"
    meshio.write(path, meshio.Mesh(pts, cells))
    return str(path)


def test_formfind_of_a_mesh_matches_the_scene_of_its_file(server, tmp_path):
    """Quads and triangles: the mesh's edges are the ropes, hung from its boundary, as a scene of the same mesh
    written to a file."""
    mesh, pts, quads, tris = grid_net(6, 4, 6.0, 4.0)
    status, text = post(server, request("FormFind", Mesh=mesh, Slack=0.05, MassPerLength=2.0))
    reply, out = outputs(text)
    assert status == 200 and reply["errors"] == []
    ref = sf.run(parse_scene({"geometry": {"type": "file", "file": mesh_file(tmp_path, pts, quads, tris)},
                              "supports": [{"groups": ["boundary"]}],
                              "ropes": {"slack": 0.05, "mass_per_length": 2.0}, "analysis": {"type": "mra"}}))
    hang = ref.mesh("hanging.vtu")
    np.testing.assert_allclose(np.array(out["HangingNet"]), lines_of(hang), rtol=0, atol=1e-12 * 6.0)
    np.testing.assert_allclose(out["RopeForces"], hang.cell_data["tension"][0], rtol=1e-12, atol=1e-9)
    shell = ref.mesh("inverted_shell.vtu")
    got = out["Shell"][0]
    assert got.Faces.Count == len(quads) + len(tris) == sum(len(c) for c in shell.cells_dict.values())
    assert out["Converged"] == [True] and ref.converged
    assert json.loads(out["Report"][0])["iterations"] == ref.summary["iterations"]


def test_a_mesh_net_hangs_from_points_curves_and_corners(server, tmp_path):
    """Support points and curves pick the mesh's nodes as the scene's near and curve keys do; corners are the
    turning points of its boundary."""
    mesh, pts, quads, tris = grid_net(6, 6, 6.0, 6.0, triangles=False)
    edge = rhino3dm.LineCurve(rhino3dm.Point3d(0.0, 0.0, 0.5), rhino3dm.Point3d(6.0, 0.0, 0.5))
    arc = rhino3dm.Circle(rhino3dm.Point3d(3.0, 6.5, 0.5), 0.5).ToNurbsCurve()  # touches the net at (3, 6)
    body = request("FormFind", Mesh=mesh, Supports="corners", SupportPoints=[[0.0, 3.0, 0.5]],
                   SupportCurves=[edge, arc])
    reply, out = outputs(post(server, body)[1])
    assert reply["errors"] == []
    held = {tuple(np.round(p, 9)) for p in out["SupportPoints"]}
    expected = {(x, 0.0, 0.5) for x in range(7)} | {(0.0, 6.0, 0.5), (6.0, 6.0, 0.5), (0.0, 3.0, 0.5),
                                                     (3.0, 6.0, 0.5)}
    assert held == {tuple(float(c) for c in p) for p in expected}
    ref = sf.run(parse_scene({"geometry": {"type": "file", "file": mesh_file(tmp_path, pts, quads, tris)},
                              "supports": [{"groups": ["corners"]}, {"near": [[0.0, 3.0, 0.5]]},
                                           {"curve": [[0.0, 0.0, 0.5], [6.0, 0.0, 0.5]], "tolerance": 0.25},
                                           {"near": [[3.0, 6.0, 0.5]]}],
                              "analysis": {"type": "mra"}}))
    np.testing.assert_allclose(np.array(out["HangingNet"]), lines_of(ref.mesh("hanging.vtu")), atol=1e-12 * 6.0)


def test_bad_mesh_inputs_name_the_input(server):
    mesh = grid_net(4, 4, 4.0, 4.0)[0]
    square = rectangle(0.0, 0.0, 4.0, 4.0)
    assert _error(server, request("FormFind", Mesh=mesh, Boundary=square)) == (
        "Mesh: give only one of Boundary or Mesh; got Boundary and Mesh")
    assert _error(server, request("FormFind", Slack=0.1)).startswith("Boundary or Mesh: one is required")
    assert _error(server, request("FormFind", Mesh=mesh, EdgeLength=0.5)).startswith(
        "EdgeLength: applies to a Boundary outline")
    assert _error(server, request("FormFind", Mesh=mesh, Supports="south")).startswith(
        "Supports: a mesh net has no node set 'south'")
    assert _error(server, request("FormFind", Mesh=mesh, Supports="", SupportPoints=[[9.0, 9.0, 0.0]])).startswith(
        "SupportPoints: item 0 at (9, 9, 0) m is no node of the structure")
    assert _error(server, request("FormFind", Mesh=rhino3dm.Mesh())).startswith("Mesh: has no faces")
    # the laths of a gridshell on a found form follow straight chains of quad edges: no triangles
    assert _error(server, request("Gridshell", Mesh=mesh)).startswith("Mesh: scene key 'geometry.file': the laths")


# -- lines as the rods of a gridshell ------------------------------------------------------------


def polyline_curve(points):
    pl = rhino3dm.Polyline(len(points))
    for p in np.asarray(points, dtype=float).tolist():
        pl.Add(*p)
    return rhino3dm.PolylineCurve(pl)


def dome_grid(n: int = 5, span: float = 4.0, rise: float = 0.8) -> np.ndarray:
    """Points (n, n, 3) of a square grid lifted onto a sine dome."""
    s = np.linspace(0.0, span, n)
    x, y = np.meshgrid(s, s, indexing="ij")
    z = rise * np.sin(np.pi * x / span) * np.sin(np.pi * y / span)
    return np.stack([x, y, z], axis=2)


def grid_lines(grid: np.ndarray) -> list:
    """The polylines along both families of a grid's lines (n, n, 3)."""
    n = len(grid)
    return [polyline_curve(grid[i, :]) for i in range(n)] + [polyline_curve(grid[:, j]) for j in range(n)]


def test_gridshell_of_lines_matches_the_rod_scene(server):
    """Polylines along both families of a dome's grid lines: rods sharing their crossing nodes, pinned at their
    ends, under their weight and node masses, traced to the first critical point as the rod scene of the same
    nodes and [[rods.lines]] is."""
    n = 5
    grid = dome_grid(n)
    curves = grid_lines(grid)
    radius, density, node_mass, mass_per_length = 0.02, 7850.0, 50.0, 3.0
    status, text = post(server, request("Gridshell", Lines=curves, Radius=radius, Density=density,
                                        NodeMass=node_mass, MassPerLength=mass_per_length, RestShape="found"))
    reply, out = outputs(text)
    assert status == 200 and reply["errors"] == [], reply["errors"]
    idx = np.arange(n * n).reshape(n, n)
    ends = np.unique(np.concatenate([idx[0], idx[-1], idx[:, 0], idx[:, -1]]))
    ref = sf.run(parse_scene({
        "nodes": {"coordinates": grid.reshape(-1, 3).tolist()},
        "rods": {"E": 210.0e9, "radius": radius, "rest_shape": "found",
                 # MassPerLength is the rods' weight per metre besides their density's
                 "density": density + mass_per_length / (np.pi * radius**2),
                 "lines": [{"nodes": idx[i].tolist()} for i in range(n)] + [{"nodes": idx[:, j].tolist()}
                                                                            for j in range(n)]},
        "masses": {"node_mass": node_mass}, "supports": [{"nodes": ends.tolist()}], "gravity": {"scaled": True},
        "analysis": {"type": "continuation", "continuation": {"control": "load", "parameter_max": 100.0,
                                                              "max_steps": 60, "on_bifurcation": "stop"}}}))
    event = ref.events[0]
    assert out["CriticalLoadFactor"] == [pytest.approx(event["lam"], rel=1e-12)]
    assert out["CriticalKind"] == [event["kind"]]
    crit = ref.mesh(event["file"])
    np.testing.assert_allclose(np.array(out["Rods"]), lines_of(crit), rtol=0, atol=1e-12 * 4.0)
    moved = np.array(out["BucklingMode"]) - np.array(out["Rods"])
    assert np.linalg.norm(moved, axis=2).max() == pytest.approx(0.1, rel=1e-9)
    scale = np.abs(crit.cell_data["axial_force"][0]).max()
    np.testing.assert_allclose(out["AxialForce"], crit.cell_data["axial_force"][0], rtol=0, atol=1e-10 * scale)
    moment = np.abs(crit.cell_data["bending_moment"][0]).max()
    np.testing.assert_allclose(out["BendingMoment"], crit.cell_data["bending_moment"][0], rtol=0,
                               atol=1e-10 * moment)


def test_a_smooth_curve_is_divided_and_joined_where_points_meet():
    """A quarter circle between two lines: divided into equal segments no longer than SegmentLength, its ends the
    lines' ends (one node each)."""
    from shellform.hops.rod_lines import rod_lines

    arc = rhino3dm.Arc(rhino3dm.Circle(2.0), np.pi / 2).ToNurbsCurve()
    legs = [rhino3dm.LineCurve(rhino3dm.Point3d(2.0, 0.0, 0.0), rhino3dm.Point3d(2.0, 0.0, -1.0)),
            [[0.0, 2.0, 0.0], [0.0, 2.0, -1.0]]]  # a line item as Hops decodes it
    lines = rod_lines([arc] + legs, 0.3)
    chain = lines.chains[0]
    assert len(chain) == int(np.ceil(np.pi / 0.3)) + 1
    step = np.linalg.norm(np.diff(lines.nodes[chain], axis=0), axis=1)
    assert step.max() <= 0.3 and np.ptp(step) < 1e-3 * step.max()
    assert len(lines.nodes) == len(chain) + 2  # the legs' tops are the arc's ends
    assert {lines.chains[1][0], lines.chains[2][0]} == {chain[0], chain[-1]}
    np.testing.assert_allclose(np.linalg.norm(lines.nodes[chain, :2], axis=1), 2.0, rtol=1e-9)


def test_bad_lines_name_the_input_and_the_problem(server):
    grid = dome_grid(4)
    curves = grid_lines(grid)
    point = rhino3dm.Point3d
    assert _error(server, request("Gridshell", Lines=curves[:1])).startswith(
        "Lines: got 1 curve; a gridshell needs at least two rods")
    zero = rhino3dm.LineCurve(point(1.0, 1.0, 0.0), point(1.0, 1.0, 0.0))
    assert _error(server, request("Gridshell", Lines=curves + [zero])) == "Lines: item 8 has zero length"
    apart = polyline_curve(grid[0, :] + [10.0, 0.0, 0.0])
    assert _error(server, request("Gridshell", Lines=curves + [apart])).startswith(
        "Lines: the curves are not connected into one structure: 2 separate parts (item 8 is not joined")
    corner = grid[0, 0].tolist()
    assert "a mechanism" in _error(server, request("Gridshell", Lines=curves, Supports="", SupportPoints=[corner]))
    assert _error(server, request("Gridshell", Lines=curves, Supports="", SupportPoints=[corner, grid[3, 3].tolist()])
                  ).startswith("Supports: the supports are 2 nodes on one line: the gridshell can turn about them")
    # a linkage of single-edge rods: the tangent is singular at the start
    square = [rhino3dm.LineCurve(point(*a), point(*b)) for a, b in
              (((0, 0, 0), (1, 0, 0)), ((1, 0, 0), (1, 1, 0)), ((1, 1, 0), (0, 1, 0)), ((0, 1, 0), (0, 0, 0)))]
    assert _error(server, request("Gridshell", Lines=square, Supports="", SupportPoints=[[0, 0, 0], [1, 0, 0],
                                                                                        [0, 1, 0]])).startswith(
        "Supports: the tangent is singular at the starting point")
    assert _error(server, request("Gridshell", Lines=curves, Boundary=rectangle(0.0, 0.0, 4.0, 4.0))) == (
        "Lines: give only one of Boundary, Mesh or Lines; got Boundary and Lines")
    assert _error(server, request("Gridshell", Lines=curves, Supports="corners")).startswith(
        "Supports: lines have no node set 'corners'")
    assert _error(server, request("Gridshell", Lines=curves, Joints="glue")).startswith(
        "Joints: scene key 'rods.joints': got 'glue'")
    assert _error(server, request("Gridshell", Lines=curves, Radius=-1.0)).startswith("Radius: scene key 'rods.radius'")
    assert _error(server, request("Gridshell", Lines=curves, SegmentLength=0.0)).startswith("SegmentLength: got 0.0")
    assert _error(server, request("Gridshell", Boundary=rectangle(0.0, 0.0, 4.0, 4.0), SegmentLength=0.5)) == (
        "SegmentLength: applies to Lines")
    # a point where a curve belongs (Hops sends what the wire carries)
    body = request("Gridshell", Lines=curves)
    body["values"][0]["InnerTree"]["{0}"].insert(0, {"type": "Rhino.Geometry.Point3d",
                                                     "data": '{"X": 0.0, "Y": 0.0, "Z": 0.0}'})
    assert _error(server, body) == "Lines: item 0 is a point or a list, not a line or a curve"


def test_gridshell_of_timber_laths_matches_the_rod_scene(server):
    """Rectangular laths (50 x 30 mm, E = 10 GPa) on the dome's lines: the section's keys reach the scene, with
    MassPerLength spread over the rectangle's area."""
    n = 5
    grid = dome_grid(n)
    curves = grid_lines(grid)
    depth, width, density, mass_per_length = 0.03, 0.05, 500.0, 2.0
    status, text = post(server, request("Gridshell", Lines=curves, Section="rectangle", Depth=depth, Width=width,
                                        E=10.0e9, Density=density, NodeMass=20.0, MassPerLength=mass_per_length,
                                        RestShape="found"))
    reply, out = outputs(text)
    assert status == 200 and reply["errors"] == [], reply["errors"]
    idx = np.arange(n * n).reshape(n, n)
    ends = np.unique(np.concatenate([idx[0], idx[-1], idx[:, 0], idx[:, -1]]))
    ref = sf.run(parse_scene({
        "nodes": {"coordinates": grid.reshape(-1, 3).tolist()},
        "rods": {"E": 10.0e9, "section": "rectangle", "depth": depth, "width": width, "rest_shape": "found",
                 "density": density + mass_per_length / (depth * width),
                 "lines": [{"nodes": idx[i].tolist()} for i in range(n)] + [{"nodes": idx[:, j].tolist()}
                                                                            for j in range(n)]},
        "masses": {"node_mass": 20.0}, "supports": [{"nodes": ends.tolist()}], "gravity": {"scaled": True},
        "analysis": {"type": "continuation", "continuation": {"control": "load", "parameter_max": 100.0,
                                                              "max_steps": 60, "on_bifurcation": "stop"}}}))
    event = ref.events[0]
    assert out["CriticalLoadFactor"] == [pytest.approx(event["lam"], rel=1e-12)]
    crit = ref.mesh(event["file"])
    moment = np.abs(crit.cell_data["bending_moment"][0]).max()
    np.testing.assert_allclose(out["BendingMoment"], crit.cell_data["bending_moment"][0], rtol=0,
                               atol=1e-10 * moment)


@pytest.mark.parametrize("inputs, name, message", [
    ({"Section": "square"}, "Section", "square"),
    ({"Depth": 0.03}, "Depth", "does not apply to section = 'circle'"),
    ({"Section": "rectangle", "Width": 0.05}, "Depth", "required for section = 'rectangle'"),
])
def test_bad_section_inputs_name_the_input(server, inputs, name, message):
    grid = dome_grid(3)
    curves = grid_lines(grid)
    error = _error(server, request("Gridshell", Lines=curves, **inputs))
    assert error.startswith(f"{name}:") and message in error, error
