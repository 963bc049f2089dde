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
from shellform.hops import start  # noqa: E402
from shellform.scene import parse_scene  # noqa: E402
from test_hops_server import lines_of, outputs, post, rectangle, request  # noqa: E402


@pytest.fixture(scope="module")
def server():
    srv, thread = start(port=0)
    yield srv
    srv.shutdown()
    srv.server_close()
    thread.join(5)


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
