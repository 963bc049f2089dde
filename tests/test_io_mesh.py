"""Mesh files as geometry, surface meshes, tables and plots: written and read back."""

import json
from pathlib import Path

import meshio
import numpy as np
import pytest

from shellform.cli import main
from shellform.errors import ModelError
from shellform.io.mesh_import import read_mesh, unique_edges
from shellform.io.shell import face_areas, surface_mesh, write_surface
from shellform.io.table import CurveStyle, plot_curve, read_csv, write_csv

ROOT = Path(__file__).resolve().parents[1]
DOME = ROOT / "meshes" / "lattice_dome.obj"


def quad_deck(path):
    """A 2 m x 1 m deck of 4 x 2 quads meshed by gmsh, its west side a physical line group."""
    import gmsh

    gmsh.initialize()
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add("deck")
        p = [gmsh.model.geo.addPoint(*x) for x in [(0, 0, 0), (2, 0, 0), (2, 1, 0), (0, 1, 0)]]
        lines = [gmsh.model.geo.addLine(p[i], p[(i + 1) % 4]) for i in range(4)]
        s = gmsh.model.geo.addPlaneSurface([gmsh.model.geo.addCurveLoop(lines)])
        gmsh.model.geo.synchronize()
        for c, n in zip(lines, [4, 2, 4, 2]):
            gmsh.model.mesh.setTransfiniteCurve(c, n + 1)
        gmsh.model.mesh.setTransfiniteSurface(s)
        gmsh.model.mesh.setRecombine(2, s)
        gmsh.model.addPhysicalGroup(1, [lines[3]], name="west")
        gmsh.model.addPhysicalGroup(2, [s], name="deck")
        gmsh.model.mesh.generate(2)
        gmsh.write(str(path))
    finally:
        gmsh.finalize()
    return path


@pytest.mark.parametrize("suffix", [".obj", ".vtu", ".msh", ".vtk"])
def test_the_same_mesh_in_any_format_gives_the_same_members(tmp_path, suffix):
    source = meshio.read(DOME)
    path = tmp_path / f"dome{suffix}"
    meshio.write(path, source)
    mesh = read_mesh(path)
    assert np.allclose(mesh.points, source.points)
    tri = source.cells_dict["triangle"]
    expected = {tuple(sorted(e)) for t in tri for e in ((t[0], t[1]), (t[1], t[2]), (t[2], t[0]))}
    assert {tuple(e) for e in mesh.edges()} == expected and len(mesh.edges()) == 90
    # 3 x edges = 2 x interior edges + boundary edges: the rim of 18 nodes and 18 edges
    assert np.array_equal(mesh.boundary_nodes(), np.arange(19, 37))


def test_line_cells_on_face_edges_are_members_once(tmp_path):
    mesh = read_mesh(quad_deck(tmp_path / "deck.msh"))
    assert set(mesh.cells) == {"line", "quad"}
    edges = mesh.edges()
    assert len(edges) == 4 * 3 + 5 * 2  # a 4 x 2 quad grid; the west lines are quad edges too
    assert len(mesh.edges(["line"])) == 2
    west = mesh.point_sets["west"]
    assert np.allclose(mesh.points[west, 0], 0.0) and len(west) == 3
    assert len(mesh.boundary_nodes()) == 12


def test_a_mesh_file_scene_supports_a_named_set_and_splits_member_groups(tmp_path):
    deck = quad_deck(tmp_path / "deck.msh")
    scene = tmp_path / "deck.toml"
    scene.write_text(f"""
[geometry]
type = "file"
file = "{deck.name}"
[[members]]
name = "edge"
kind = "bar"
cells = ["line"]
EA = 1.0e7
[[members]]
name = "net"
kind = "rope"
EA = 1.0e5
mass_per_length = 1.0
[[supports]]
groups = ["west"]
[[supports]]
nodes = [1, 2]
[gravity]
""")
    out = tmp_path / "out"
    assert main(["run", str(scene), "--out", str(out), "--quiet"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["n_members"] == 22 and summary["effects"] == ["axial", "rope", "gravity"]
    state = meshio.read(out / "state.vtu")
    assert list(np.bincount(state.cell_data["group"][0])) == [2, 20]


def test_unreadable_and_unsuitable_files_are_named(tmp_path):
    with pytest.raises(ModelError, match="does not exist"):
        read_mesh(tmp_path / "missing.vtu")
    (tmp_path / "junk.vtu").write_text("not a mesh")
    with pytest.raises(ModelError, match="cannot read mesh file"):
        read_mesh(tmp_path / "junk.vtu")
    tet = meshio.Mesh(np.eye(4, 3), [("tetra", np.array([[0, 1, 2, 3]]))])
    meshio.write(tmp_path / "tet.vtu", tet)
    with pytest.raises(ModelError, match="no line, triangle or quad cells"):
        read_mesh(tmp_path / "tet.vtu")


def test_unique_edges_keep_the_first_appearance():
    e = unique_edges(np.array([[3, 1], [0, 2], [1, 3], [2, 0], [4, 1]]))
    assert e.tolist() == [[1, 3], [0, 2], [1, 4]]


def test_surface_mesh_of_quads_and_triangles_with_areas(tmp_path):
    pts = np.array([[0.0, 0, 0], [2, 0, 0], [2, 1, 0], [0, 1, 0], [0, 1, 1]])
    assert face_areas(pts, [[0, 1, 2, 3]]) == pytest.approx([2.0])
    assert face_areas(pts, [[0, 3, 4]]) == pytest.approx([0.5])
    path = write_surface(tmp_path / "s.vtu", pts, [[0, 1, 2, 3]], {"height": pts[:, 2]})
    back = meshio.read(path)
    assert list(back.cells_dict) == ["quad"] and back.cells_dict["quad"].tolist() == [[0, 1, 2, 3]]
    assert back.cell_data["area"][0] == pytest.approx([2.0])
    assert np.allclose(back.point_data["height"], pts[:, 2])
    assert surface_mesh(pts, [[0, 3, 4]]).cells[0].type == "triangle"


def test_table_round_trip_is_exact(tmp_path):
    table = {"step": np.arange(4), "x": np.array([0.1, 1 / 3, -2.5e-17, 1e300]), "ok": [True, False, True, True],
             "label": ["U+", "O+", "W", "S"]}
    back = read_csv(write_csv(tmp_path / "t.csv", table))
    assert back["step"].dtype.kind == "i" and list(back["step"]) == [0, 1, 2, 3]
    assert np.array_equal(back["x"], table["x"])
    assert list(back["ok"]) == [1, 0, 1, 1] and list(back["label"]) == table["label"]
    with pytest.raises(ValueError, match="different lengths"):
        write_csv(tmp_path / "bad.csv", {"a": [1, 2], "b": [1]})
    with pytest.raises(KeyError, match="no column"):
        write_csv(tmp_path / "bad.csv", table, ["step", "y"])


def test_curve_plot_with_branches_and_marks(tmp_path):
    x = np.linspace(0, 1, 20)
    style = CurveStyle(marks=[(0.26, 1.0, "limit")], stable=np.cos(6 * x) > 0, branch=(x > 0.5).astype(int))
    path = plot_curve(tmp_path / "c.png", x, np.sin(6 * x), "x", "y", "a curve", style)
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and path.stat().st_size > 10_000
    assert not list(tmp_path.glob(".c-*"))
