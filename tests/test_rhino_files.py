"""Rhino files both ways: a .3dm written here goes in as a scene, the results come out as a .3dm with user text."""

from __future__ import annotations

import numpy as np
import pytest

rhino3dm = pytest.importorskip("rhino3dm")

import shellform as sf  # noqa: E402
from shellform.errors import SceneError  # noqa: E402
from shellform.io.rhino_import import read_3dm  # noqa: E402

FEET = [(1.0, 0.0, 0.0), (-0.5, 0.866, 0.0), (-0.5, -0.866, 0.0)]
TOP = (0.0, 0.0, 1.0)


def _model(units="Millimeters"):
    model = rhino3dm.File3dm()
    model.Settings.ModelUnitSystem = getattr(rhino3dm.UnitSystem, units)
    model.Settings.ModelAbsoluteTolerance = 0.01
    return model


def _on(model, name):
    lay = rhino3dm.Layer()
    lay.Name = name
    attrs = rhino3dm.ObjectAttributes()
    attrs.LayerIndex = model.Layers.Add(lay)
    return attrs


def tripod_file(path):
    """Three bars in millimetres on layer 'bars', the feet as points on 'supports', an arc on 'sketch'."""
    model = _model()
    bars, feet, sketch = _on(model, "bars"), _on(model, "supports"), _on(model, "sketch")
    mm = lambda p: rhino3dm.Point3d(*(1000.0 * c for c in p))  # noqa: E731
    for p in FEET:
        model.Objects.AddLine(mm(p), mm(TOP), bars)
        model.Objects.AddPoint(mm(p), feet)
    model.Objects.AddCircle(rhino3dm.Circle(mm((5.0, 5.0, 0.0)), 500.0), sketch)
    assert model.Write(str(path), 7)
    return path


SCENE = """
[geometry]
type = "file"
file = "tripod.3dm"
layers = ["bars", "supports"]
[[members]]
kind = "bar"
EA = 1.0e6
[[supports]]
groups = ["supports"]
[[loads]]
nodes = [1]
force = [0.0, 0.0, -1000.0]
[output]
formats = ["vtu", "3dm"]
"""


def test_a_3dm_file_is_a_scene_and_its_results_come_back_as_3dm(tmp_path):
    tripod_file(tmp_path / "tripod.3dm")
    (tmp_path / "scene.toml").write_text(SCENE)
    result = sf.run(tmp_path / "scene.toml", out=tmp_path / "out")
    assert result.converged
    # the same tripod given node by node, in metres
    nodes = sf.scene_from_toml(f"""
[nodes]
coordinates = {[list(FEET[0]), list(TOP), list(FEET[1]), list(FEET[2])]}
[[members]]
kind = "bar"
connectivity = [[0, 1], [2, 1], [3, 1]]
EA = 1.0e6
[[supports]]
nodes = [0, 2, 3]
[[loads]]
nodes = [1]
force = [0.0, 0.0, -1000.0]
""")
    ref = sf.run(nodes)
    state, expected = result.mesh(), ref.mesh()
    np.testing.assert_allclose(state.points, expected.points, rtol=0, atol=1e-12)
    np.testing.assert_allclose(state.cell_data["axial_force"][0], expected.cell_data["axial_force"][0], rtol=1e-12)
    # the results file: units, members with their results, supports with reactions, reactions as lines
    model = rhino3dm.File3dm.Read(str(tmp_path / "out" / "state.3dm"))
    assert str(model.Settings.ModelUnitSystem).endswith("Meters")
    layers = {lay.Index: lay.FullPath for lay in model.Layers}
    by_layer = {}
    for obj in model.Objects:
        by_layer.setdefault(layers[obj.Attributes.LayerIndex], []).append(obj)
    assert set(by_layer) == {"members::bars0", "supports", "reactions"}
    force = state.cell_data["axial_force"][0]
    for obj in by_layer["members::bars0"]:
        text = dict(obj.Attributes.GetUserStrings())
        m = int(text["member"])
        assert float(text["axial_force [N]"]) == force[m]
        assert float(text["strain [-]"]) == state.cell_data["strain"][0][m]
        assert "slack [-]" not in text  # bars have no slack: left out, not 0
        a, b = state.cells_dict["line"][m]
        line = obj.Geometry
        np.testing.assert_allclose([[line.PointAtStart.X, line.PointAtStart.Y, line.PointAtStart.Z],
                                    [line.PointAtEnd.X, line.PointAtEnd.Y, line.PointAtEnd.Z]],
                                   state.points[[a, b]], atol=1e-12)
    R = state.point_data["reaction"]
    assert len(by_layer["supports"]) == 3 and len(by_layer["reactions"]) == 3
    total = np.zeros(3)
    for obj in by_layer["supports"]:
        text = dict(obj.Attributes.GetUserStrings())
        n = int(text["node"])
        assert text["dofs"] == "xyz"
        got = [float(text[f"reaction_{c} [N]"]) for c in "xyz"]
        np.testing.assert_allclose(got, R[n], rtol=1e-12)
        total += got
    np.testing.assert_allclose(total, [0.0, 0.0, 1000.0], atol=1e-6)


def test_buckling_modes_are_layers_of_the_state_file(tmp_path):
    from shellform.scene import load_scene
    from shellform.api import builtin_scene_path

    scene = load_scene(builtin_scene_path("von_mises"))
    scene["output"]["formats"] = ["vtu", "3dm"]
    result = sf.run(scene, out=tmp_path)
    model = rhino3dm.File3dm.Read(str(tmp_path / "state.3dm"))
    names = [lay.FullPath for lay in model.Layers]
    assert "mode 1 (limit point)" in names and "mode 2 (limit point)" in names
    scale = float(model.Strings["mode_scale [m]"])
    mode = result.mode(1)
    crit = result.mesh(result.events[0]["file"])
    layer = names.index("mode 1 (limit point)")
    lines = [o.Geometry for o in model.Objects if o.Attributes.LayerIndex == model.Layers[layer].Index]
    apex = crit.points[1] + scale * mode[1]
    assert any(np.allclose([ln.PointAtEnd.X, ln.PointAtEnd.Y, ln.PointAtEnd.Z], apex, atol=1e-12) for ln in lines)


def test_form_file_holds_the_rope_results(tmp_path):
    result = sf.run(sf.scene_from_toml("""
[geometry]
type = "rectangle"
length_x = 4.0
length_y = 3.0
n_i = 4
n_j = 3
[[supports]]
groups = ["boundary"]
[ropes]
slack = 0.05
[output]
formats = ["vtu", "3dm"]
"""), out=tmp_path)
    model = rhino3dm.File3dm.Read(str(tmp_path / "form.3dm"))
    layers = {lay.Index: lay.FullPath for lay in model.Layers}
    hang = result.mesh("hanging.vtu")
    ropes = [o for o in model.Objects if layers[o.Attributes.LayerIndex] == "hanging net"]
    assert len(ropes) == len(hang.cells_dict["line"])
    for obj in ropes:
        text = dict(obj.Attributes.GetUserStrings())
        m = int(text["member"])
        assert float(text["axial_force [N]"]) == hang.cell_data["tension"][0][m]
        assert float(text["length [m]"]) == hang.cell_data["length"][0][m]
        assert text["slack [-]"] in ("0", "1") and text["length_class [-]"].isdigit()


def test_reading_curves_points_and_meshes(tmp_path):
    model = _model("Meters")
    net, arch, sup = _on(model, "roof::net"), _on(model, "arch"), _on(model, "supports")
    mesh = rhino3dm.Mesh()
    for p in [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (2, 0, 0), (2, 1, 0)]:
        mesh.Vertices.AddPoint3d(*map(float, p))
    mesh.Faces.AddFace(0, 1, 2, 3)
    mesh.Faces.AddFace(1, 4, 5, 2)
    model.Objects.AddMesh(mesh, net)
    model.Objects.AddArc(rhino3dm.Arc(rhino3dm.Point3d(0, 0, 0), rhino3dm.Point3d(1, 0, 1.0),
                                      rhino3dm.Point3d(2, 0, 0)), arch)
    model.Objects.AddPoint(rhino3dm.Point3d(2, 1, 0), sup)
    model.Write(str(tmp_path / "m.3dm"), 7)
    with pytest.raises(Exception, match="not a polyline; give segment_length"):
        read_3dm(tmp_path / "m.3dm")
    got = read_3dm(tmp_path / "m.3dm", segment_length=0.2)
    assert len(got.cells["quad"]) == 2 and len(got.edges(["quad"])) == 7
    arch_edges = got.cells["line"]
    seg = np.linalg.norm(got.points[arch_edges[:, 0]] - got.points[arch_edges[:, 1]], axis=1)
    # a half circle of radius 1 in segments of at most 0.2 m (chords of equal arcs)
    assert len(seg) == 16 and seg.max() <= 0.2 and np.ptp(seg) < 1e-3
    # the arch's ends are the mesh's corners: one node each
    assert len(got.points) == 6 + 15
    assert set(got.point_sets) >= {"roof::net", "net", "arch", "supports"}
    assert got.point_sets["supports"].tolist() == [5]
    only = read_3dm(tmp_path / "m.3dm", layers=["roof"])
    assert set(only.cells) == {"quad"}


def test_rhino_scene_errors_name_the_key(tmp_path):
    tripod_file(tmp_path / "tripod.3dm")
    (tmp_path / "scene.toml").write_text(SCENE.replace('["bars", "supports"]', '["bars", "nope"]'))
    with pytest.raises(SceneError, match=r"geometry.file.*no layer 'nope'.*'bars'"):
        sf.run(tmp_path / "scene.toml")
    (tmp_path / "scene.toml").write_text(SCENE.replace('layers = ["bars", "supports"]\n', ""))
    with pytest.raises(SceneError, match="circle.*not a polyline|not a polyline"):
        sf.run(tmp_path / "scene.toml")  # the arc on 'sketch' needs segment_length
    (tmp_path / "scene.toml").write_text(SCENE.replace("tripod.3dm", "net.vtu"))
    with pytest.raises(SceneError, match=r"geometry.layers.*Rhino files \(.3dm\) only"):
        sf.run(tmp_path / "scene.toml")
    model = _model()
    model.Objects.AddLine(rhino3dm.Point3d(0, 0, 0), rhino3dm.Point3d(1000, 0, 0), _on(model, "bars"))
    model.Objects.AddPoint(rhino3dm.Point3d(500, 500, 0), _on(model, "supports"))
    model.Write(str(tmp_path / "tripod.3dm"), 7)
    (tmp_path / "scene.toml").write_text(SCENE)
    with pytest.raises(SceneError, match=r"on layer 'supports' at \(0.5, 0.5, 0\) m lies on no curve"):
        sf.run(tmp_path / "scene.toml")
