"""Rhino export, read back with rhino3dm."""

import numpy as np
import pytest

rhino3dm = pytest.importorskip("rhino3dm")

from shellform.io.rhino import write_3dm  # noqa: E402


def test_lines_polylines_and_mesh_round_trip(tmp_path):
    pts = np.array([[0.0, 0, 0], [1, 0, 0], [1, 1, 0.5], [0, 1, 0.5]])
    path = write_3dm(
        tmp_path / "shape.3dm",
        lines={"ropes": (pts, np.array([[0, 1], [1, 2]]))},
        polylines={"rods": [pts[:3], pts[1:]]},
        meshes={"shell": (pts, np.array([[0, 1, 2, 3]]))},
    )
    model = rhino3dm.File3dm.Read(str(path))
    assert sorted(layer.Name for layer in model.Layers) == ["rods", "ropes", "shell"]
    kinds = [type(obj.Geometry).__name__ for obj in model.Objects]
    assert kinds.count("LineCurve") == 2
    assert kinds.count("PolylineCurve") == 2
    assert kinds.count("Mesh") == 1
    mesh = next(o.Geometry for o in model.Objects if type(o.Geometry).__name__ == "Mesh")
    assert len(mesh.Vertices) == 4
    v = mesh.Vertices[2]
    assert (v.X, v.Y, v.Z) == pytest.approx((1.0, 1.0, 0.5))
    line = next(o.Geometry for o in model.Objects if type(o.Geometry).__name__ == "LineCurve")
    assert line.PointAtEnd.X == pytest.approx(1.0)


def test_static_scene_writes_a_rhino_file(tmp_path):
    from shellform.cli import main

    scene = tmp_path / "chain.toml"
    scene.write_text("""
[nodes]
coordinates = [[0.0, 0.0, 0.0], [1.0, 0.0, -0.5], [2.0, 0.0, 0.0]]
[[members]]
name = "chain"
kind = "rope"
connectivity = [[0, 1], [1, 2]]
EA = 1.0e5
mass_per_length = 1.0
[[supports]]
nodes = [0, 2]
[gravity]
[output]
formats = ["3dm"]
""")
    assert main(["run", str(scene), "--out", str(tmp_path / "out"), "--quiet"]) == 0
    model = rhino3dm.File3dm.Read(str(tmp_path / "out" / "state.3dm"))
    assert [layer.FullPath for layer in model.Layers] == ["members", "members::chain", "supports", "reactions"]
    kinds = sorted(type(o.Geometry).__name__ for o in model.Objects)
    assert kinds == ["LineCurve"] * 4 + ["Point"] * 2  # two ropes, two reactions, two supports
