"""Bad models are rejected with a message that names the problem and where it is."""

import numpy as np
import pytest

import shellform as sf
from shellform.errors import MechanismError, ModelError


def square():
    return sf.Structure([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]])


def test_zero_length_member_is_named():
    s = sf.Structure([[0, 0, 0], [1, 0, 0], [1, 0, 0]])
    with pytest.raises(ModelError, match=r"member 1 \(nodes 1-2\) has zero length"):
        s.add_bars([[0, 1], [1, 2]], EA=1.0, name="chords")
    with pytest.raises(ModelError, match="zero length"):
        s.add_ropes([[1, 2]], EA=1.0)


def test_member_to_itself():
    with pytest.raises(ModelError, match="member 0 connects node 2 to itself"):
        square().add_bars([[2, 2]], EA=1.0)


@pytest.mark.parametrize(
    "call",
    [
        lambda s: s.add_bars([[0, 1], [1, 7]], EA=1.0),
        lambda s: s.fix([4]),
        lambda s: s.add_load([-1], [0, 0, 1]),
        lambda s: s.prescribe([10], [0, 0, -1]),
    ],
)
def test_node_index_out_of_range(call):
    with pytest.raises(ModelError, match=r"out of range \(the model has 4 nodes"):
        call(square())


@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_non_finite_coordinate_is_located(bad):
    nodes = np.zeros((3, 3))
    nodes[1] = [1, 0, 0]
    nodes[2, 1] = bad
    with pytest.raises(ModelError, match="coordinate y of node 2 is not finite"):
        sf.Structure(nodes)


def test_bad_properties():
    with pytest.raises(ModelError, match="EA: value of member 1 must be positive"):
        square().add_bars([[0, 1], [1, 2]], EA=[1.0, 0.0])
    with pytest.raises(ModelError, match="EA: value of member 0 is not finite"):
        square().add_bars([[0, 1]], EA=np.nan)
    with pytest.raises(ModelError, match="x, y, z"):
        square().fix([0], "xq")
    with pytest.raises(ModelError, match="slack coefficient"):
        square().add_ropes([[0, 1]], EA=1.0, slack=-2.0)


def test_unsupported_structure_is_a_mechanism():
    s = square()
    s.add_bars([[0, 1], [1, 2], [2, 3], [3, 0], [0, 2]], EA=1.0)
    with pytest.raises(MechanismError, match="can translate freely along x"):
        sf.build_system(s)
    s.fix([0], "z")
    s.fix([1], "z")
    with pytest.raises(MechanismError, match="along x"):
        sf.build_system(s)
    s.fix([0], "xy")
    sf.build_system(s)  # restrained now


def test_loose_node_is_a_mechanism():
    s = square()
    s.add_bars([[0, 1], [1, 2]], EA=1.0)
    s.fix([0, 1, 2])
    with pytest.raises(MechanismError, match=r"node 3 \(not attached to any member\)"):
        sf.build_system(s)


def test_mechanism_stabilised_by_its_load_is_solved_through_the_singular_start():
    # a straight pinned-pinned chain has no transverse stiffness at the start:
    # the tangent is singular, the solver regularises and finds the sagged state
    s = sf.Structure([[0, 0, 0], [1, 0, 0], [2, 0, 0]])
    s.add_bars([[0, 1], [1, 2]], EA=1.0)
    s.fix([0, 2])
    s.fix([1], "y")
    s.add_load([1], [0, 0, -1.0])
    res = sf.solve_static(sf.build_system(s))
    assert res.success, res.message
    assert res.regularised_steps >= 1
    # analytic: 2 N sin(theta) = P with N = EA (1/cos(theta) - 1)
    w = -res.q[5]
    l = np.hypot(1.0, w)
    assert 2 * (l - 1.0) * w / l == pytest.approx(1.0, rel=1e-9)


def test_coordinate_beyond_double_precision_is_named_not_called_zero_length():
    with pytest.raises(ModelError, match="coordinate x of node 1 is 1e\\+300"):
        sf.Structure([[0, 0, 0], [1e300, 0, 0], [2e300, 0, 0]])


# -- scenes: every class of bad input is refused at load, naming the key, the value and what is allowed ------

import copy  # noqa: E402
import os  # noqa: E402
from pathlib import Path  # noqa: E402

from shellform.cli import main  # noqa: E402
from shellform.errors import SceneError  # noqa: E402
from shellform.scene import load_scene, parse_scene  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]

TRUSS = {
    "title": "two bars",
    "nodes": {"coordinates": [[-1.0, 0.0, 0.0], [0.0, 0.0, 0.2], [1.0, 0.0, 0.0]]},
    "members": [{"kind": "bar", "connectivity": [[0, 1], [1, 2]], "EA": 1.0e4}],
    "supports": [{"nodes": [0, 2]}, {"nodes": [1], "dofs": "y"}],
    "loads": [{"nodes": [1], "force": [0.0, 0.0, -1.0]}],
}
NET = {
    "geometry": {"type": "rectangle", "length_x": 8.0, "length_y": 4.0, "n_i": 8, "n_j": 4},
    "supports": {"frames": [{"from": [0, 0], "to": [8, 0], "rise": 1.0}, {"from": [0, 4], "to": [8, 4]}]},
    "ropes": {"slack": 0.05},
}


def edited(base, path, value):
    scene = copy.deepcopy(base)
    node = scene
    for key in path[:-1]:
        node = node[key]
    node[path[-1]] = value
    return scene


@pytest.mark.parametrize("base, path, value, key, words", [
    # silent coercion: booleans and strings are not numbers, inside arrays too
    (TRUSS, ("nodes", "coordinates", 1, 2), True, "nodes.coordinates[1, 2]", "got True; expected a number"),
    (TRUSS, ("members", 0, "EA"), [1.0e4, "0.5"], "members[0].EA[1]", "got '0.5'; expected a number"),
    (TRUSS, ("members", 0, "connectivity", 1), [1, True], "members[0].connectivity[1, 1]", "expected an integer"),
    (TRUSS, ("loads", 0, "force"), [0, "0", -1], "loads[0].force[1]", "expected a number"),
    (TRUSS, ("supports", 0, "nodes"), [0, 2.0], "supports[0].nodes[1]", "expected an integer"),
    # magnitudes: the key and the node, not a zero-length member
    (TRUSS, ("nodes", "coordinates", 1, 0), 1e300, "nodes.coordinates[1, 0]", "coordinate x of node 1"),
    (TRUSS, ("nodes", "coordinates", 2, 2), -2e6, "nodes.coordinates[2, 2]", "magnitude <= 1e6 m"),
    (TRUSS, ("members", 0, "EA"), 1e300, "members[0].EA", "magnitude <= 1e12 N"),
    (TRUSS, ("loads", 0, "force", 2), -1e200, "loads[0].force[2]", "magnitude <= 1e12 N"),
    (TRUSS, ("members", 0, "connectivity", 1, 1), 10**40, "members[0].connectivity[1, 1]", "magnitude <= 1e9"),
    (TRUSS, ("members", 0, "connectivity", 0), [0, 1, 2], "members[0].connectivity", "entry [0] has 3 numbers"),
    (NET, ("ropes", "slack"), 1e300, "ropes.slack", "<= 10.0"),
    (NET, ("ropes", "slack"), [0.05, -1.0], "ropes.slack[1]", "> -1.0"),
    # sizes and text
    (TRUSS, ("title",), "x" * 201, "title", "at most 200"),
    (TRUSS, ("title",), "a\x00b", "title", "control character"),
    (TRUSS, ("name",), "../../elsewhere", "name", "it names a folder"),
    (TRUSS, ("title",), [[[[[[[[[[[[[["deep"]]]]]]]]]]]]]], "title", "expected a string"),
    (NET, ("geometry",), {"type": "rectangle", "length_x": 8.0, "length_y": 4.0, "n_i": 5000, "n_j": 5000},
     "geometry.n_i", "at most 2,000,000"),
    # grid positions and frames out of range are named before a grid is built
    (NET, ("supports", "frames", 0, "to"), [10**9, 0], "supports.frames[0].to", "out of range"),
    (NET, ("supports", "frames", 1, "to"), [8, -9], "supports.frames[1].to", "out of range"),
    (NET, ("supports", "frames", 1, "to"), [7, 3], "supports.frames[1]", "not along one grid line"),
    (NET, ("supports",), {"positions": [[0, 0], [9, 0]]}, "supports.positions[1]", "the grid has 9 x 5 nodes"),
    (NET, ("supports",), {"nodes": [0, 45]}, "supports.nodes[1]", "out of range"),
])
def test_bad_scene_value_names_its_key(base, path, value, key, words):
    with pytest.raises(SceneError) as info:
        parse_scene(edited(base, path, value))
    assert info.value.key == key
    assert words in info.value.problem


@pytest.mark.parametrize("continuation, key, words", [
    ({"parameter_max": -1.0}, "parameter_max", "expected a number > 0 (the path starts at parameter 0"),
    ({"parameter_min": -1.0}, "parameter_max", "needs a scale"),
    ({"parameter_max": 1.0, "parameter_min": 0.5}, "parameter_min", "expected a number <= 0"),
    ({"parameter_max": 1e300}, "parameter_max", "magnitude <= 1e12"),
])
def test_continuation_bounds_are_named_not_left_to_the_solver(continuation, key, words):
    scene = {**copy.deepcopy(TRUSS), "analysis": {"type": "continuation", "continuation": continuation}}
    with pytest.raises(SceneError) as info:
        parse_scene(scene)
    assert info.value.key == f"analysis.continuation.{key}"
    assert words in info.value.problem


@pytest.mark.parametrize("edit, words", [
    ({"loads": [{"nodes": [1], "force": [0.0, 0.0, -1.0], "scaled": False}]}, "'load' control needs a load"),
    ({"effects": {"include": ["axial"]}}, "'load' control needs a load"),
    ({"analysis": {"type": "continuation", "continuation": {"control": "displacement", "parameter_max": 0.1}}},
     "'displacement' control needs a [[prescribed]] motion"),
])
def test_continuation_parameter_must_act_on_the_structure(edit, words):
    scene = {**copy.deepcopy(TRUSS), "analysis": {"type": "continuation", "continuation": {"parameter_max": 1.0}},
             **edit}
    with pytest.raises(SceneError) as info:
        parse_scene(scene)
    assert info.value.key == "analysis.continuation.control"
    assert words in info.value.problem


@pytest.mark.parametrize("geometry, key, words", [
    ({"n": 5, "voronoi_length": 0.5}, "geometry.voronoi_length", "joint spacing"),
    ({"n": 9999, "voronoi_length": 1e-6}, "geometry.voronoi_length", "at most 2,000,000"),
    ({"n": 3, "radius": 0.05, "voronoi_length": 5e-3, "rods": {"radius": 400.0}}, "rods.radius",
     "half the joint spacing"),
    ({"n": 3, "radius": 0.05, "voronoi_length": 5e-3, "rods": {"radius": 2e-12}}, "rods.radius",
     "at most 1000 times their radius"),
])
def test_hemisphere_sizes_are_named_before_building(geometry, key, words):
    rods = geometry.pop("rods", None)
    with pytest.raises(SceneError) as info:
        parse_scene({"geometry": {"type": "hemisphere", **geometry}, **({"rods": rods} if rods else {})})
    assert info.value.key == key and words in info.value.problem


@pytest.mark.parametrize("content, words", [
    (b'title = "caf\xe9"\n', "not UTF-8 text: byte 0xe9 at line 1, column 13"),
    (b"title = 'a'\n[nodes\n", "not valid TOML: Expected ']' at the end of a table declaration (at line 2"),
    (b"a = " + b"[" * 3000 + b"]" * 3000, "nested hundreds of levels deep"),
    (b"a = " + b"9" * 5000, "an integer of thousands of digits"),
])
def test_unreadable_scene_text_is_named(tmp_path, content, words):
    path = tmp_path / "bad.toml"
    path.write_bytes(content)
    with pytest.raises(SceneError, match="bad.toml") as info:
        load_scene(path)
    assert words in info.value.problem
    assert main(["run", str(path), "--out", str(tmp_path / "out"), "--quiet"]) == 2


def test_only_regular_files_are_scenes(tmp_path):
    fifo = tmp_path / "pipe.toml"
    os.mkfifo(fifo)
    for path in (tmp_path, fifo, Path("/dev/zero")):
        with pytest.raises(SceneError, match="not a regular file"):
            load_scene(path)


def _mesh_scene(tmp_path, file):
    path = tmp_path / "scene.toml"
    path.write_text(f'[geometry]\ntype = "file"\nfile = "{file}"\n[[members]]\nkind = "bar"\nEA = 1.0\n'
                    "[[supports]]\nz = 0.0\n")
    return path


@pytest.mark.parametrize("name, content, words", [
    ("junk.stl", "solid x\n  facet normal 0 0 SECRET-LINE\n", "cannot read mesh file"),
    ("dome.xyz", "v 0 0 0\n", "has extension '.xyz', which names no mesh format"),
    ("far.obj", "v 1e300 0 0\nv 0 0 0\nv 1 0 0\nf 1 2 3\n", "point 0 has a coordinate of magnitude 1e+300"),
    ("index.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 99\n", "triangle cell 0 refers to point 98"),
    ("folder.obj", None, "is not a regular file"),
])
def test_mesh_file_is_a_regular_file_of_a_mesh_format_and_never_quoted(tmp_path, name, content, words):
    if content is None:
        (tmp_path / name).mkdir()
    else:
        (tmp_path / name).write_text(content)
    with pytest.raises(SceneError) as info:
        load_scene(_mesh_scene(tmp_path, name))  # relative to the scene file's folder
    assert info.value.key == "geometry.file"
    assert words in info.value.problem
    assert "SECRET" not in str(info.value)


def test_mesh_file_may_not_be_a_device(tmp_path):
    with pytest.raises(SceneError, match="is not a regular file"):
        load_scene(_mesh_scene(tmp_path, "/dev/zero"))
    # a relative name is resolved from the scene file's folder, not from the working directory
    mesh = (ROOT / "meshes" / "lattice_dome.obj").read_text()
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "dome.obj").write_text(mesh)
    assert len(load_scene(_mesh_scene(tmp_path, "sub/dome.obj"))["mesh"].points) == 37
