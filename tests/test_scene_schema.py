"""One schema for every scene: older layouts read the same, bad keys are named."""

import copy
import sys
from pathlib import Path

import numpy as np
import pytest

from shellform.cli import main
from shellform.errors import SceneError
from shellform.scene import SCENE, load_scene, mra_params, parse_scene
from shellform.scene.schema import Key, Table, check_table

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

ROOT = Path(__file__).resolve().parents[1]

NET = {
    "geometry": {"type": "rectangle", "length_x": 9.0, "length_y": 4.0, "n_i": 9, "n_j": 4},
    "supports": [{"positions": [[0, 0], [-1, 0], [0, -1], [-1, -1], [0, 2], [-1, 2]]}],
    "ropes": {"slack": 0.05, "mass_per_length": 1.0, "stiffness_ratio": 1.0e4},
    "analysis": {"type": "mra", "relaxation": {"scheme": "implicit", "rtol": 1e-8},
                 "start_shape": {"type": "nurbs", "depth": 1.8, "compare_flat": True},
                 "lengths": {"tolerance": 0.001, "target": 1.05}},
}
LEGACY_NET = {
    "name": "net_9x4",
    "geometry": NET["geometry"],
    "supports": {"positions": NET["supports"][0]["positions"]},
    "ropes": NET["ropes"],
    "solver": {"scheme": "implicit", "rtol": 1e-8},
    "start": {"type": "nurbs", "depth": 1.8, "compare_flat": True},
    "lengths": {"tolerance": 0.001, "target": 1.05},
    "loads": {"gravity": [0.0, 0.0, -9.81]},
}


@pytest.mark.parametrize("path", sorted((ROOT / "validation" / "mra").glob("*.toml")), ids=lambda p: p.stem)
def test_mra_validation_scenes_keep_working(path):
    raw = tomllib.loads(path.read_text())
    params = mra_params(load_scene(path))
    # the parameters handed to the MRA runner are the file's own, with defaults filled
    for table in ("geometry", "ropes", "solver", "start", "lengths"):
        for key, value in raw.get(table, {}).items():
            assert params[table][key] == value, (table, key)
    for key, value in raw["supports"].items():
        if key == "frames":  # a frame without a rise gets the default rise 0
            value = [{"rise": 0.0, **f} for f in value]
        assert params["supports"][key] == value
    assert params["name"] == raw["name"]


def test_older_layout_and_the_one_schema_give_the_same_case():
    old = mra_params(parse_scene(copy.deepcopy(LEGACY_NET)))
    new = mra_params(parse_scene({**copy.deepcopy(NET), "name": "net_9x4"}))
    assert old == new


def test_older_buckling_table_splits_into_rods_and_analysis():
    scene = parse_scene({**copy.deepcopy(LEGACY_NET), "buckling": {"E": 7.0e10, "radius": 0.01,
                                                                   "load_factor_max": 50.0}})
    assert scene["analysis"]["type"] == "form_and_buckle"
    assert scene["rods"]["E"] == 7.0e10 and scene["rods"]["radius"] == 0.01
    assert scene["analysis"]["buckling"]["load_factor_max"] == 50.0


def test_default_analysis_follows_the_geometry():
    assert parse_scene(copy.deepcopy(NET) | {"analysis": {}})["analysis"]["type"] == "mra"
    with_buckling = copy.deepcopy(NET)
    with_buckling["analysis"] = {"buckling": {"load_factor_max": 10.0}}
    assert parse_scene(with_buckling)["analysis"]["type"] == "form_and_buckle"
    hemi = parse_scene({"geometry": {"type": "hemisphere", "n": 5}})
    assert hemi["analysis"]["type"] == "indentation"
    assert hemi["geometry"]["voronoi_length"] == 1.0e-3


def _edit(base, path, value):
    scene = copy.deepcopy(base)
    node = scene
    for key in path[:-1]:
        node = node.setdefault(key, {}) if isinstance(node, dict) else node[key]
    if value is None:
        node.pop(path[-1])
    else:
        node[path[-1]] = value
    return scene


BARS = {
    "nodes": {"coordinates": [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]]},
    "members": [{"kind": "bar", "connectivity": [[0, 1], [1, 2]], "EA": 1.0}],
    "supports": [{"nodes": [0, 2]}],
}


@pytest.mark.parametrize("base, path, value, key, words", [
    (NET, ("geometry", "radius"), 3.0, "geometry.radius", "does not apply to type = 'rectangle'"),
    (NET, ("geometry", "n_i"), None, "geometry.n_i", "required for type = 'rectangle'"),
    (NET, ("geometry", "n_i"), 10**9, "geometry.n_i", "<= 10000"),
    (NET, ("geometry", "type"), "torus", "geometry.type", "'rectangle', 'ellipse'"),
    (NET, ("analysis", "type"), "static", "analysis.type", "allowed: 'mra', 'form_and_buckle'"),
    (NET, ("analysis", "dynamics"), {"time_step": 1.0}, "analysis.dynamics", "applies to 'dynamics'"),
    (NET, ("analysis", "relaxation", "scheme"), "euler", "analysis.relaxation.scheme", "'implicit', 'rk4'"),
    (NET, ("analysis", "relaxation", "start"), "sideways", "analysis.relaxation.start", "'auto', 'reference'"),
    (NET, ("analysis", "relaxation", "linear_solver"), "magic", "analysis.relaxation.linear_solver", "'cholesky'"),
    (NET, ("analysis", "start_shape", "depth"), None, "analysis.start_shape.depth", "needs a depth"),
    (NET, ("supports",), [{"positions": [[0, 0]], "dofs": "w"}, {"groups": ["corners"]}], "supports[0].dofs",
     "letters x, y, z"),
    (NET, ("supports",), [{"z": 0.0}], "supports[0].z", "a planform is flat"),
    (NET, ("supports",), [{"frames": [{"from": [0, 0]}]}], "supports[0].frames[0].to", "required"),
    (NET, ("members",), [], "members", "applies to [nodes] and mesh-file scenes"),
    (NET, ("ropes", "slack"), [0.1, 0.2, 0.3], "ropes.slack", "[sc_i, sc_j]"),
    (BARS, ("ropes",), {"slack": 0.1}, "ropes", "applies to form finding"),
    (BARS, ("geometry",), {"type": "rectangle"}, "geometry.length_x", "required"),
    (BARS, ("members", 0, "connectivity"), None, "members[0].connectivity", "required with [nodes]"),
    (BARS, ("supports",), [{"dofs": "z"}], "supports[0]", "names no nodes"),
    (BARS, ("supports",), [{"groups": ["boundary"]}], "supports[0].groups", "this scene has [nodes]"),
    (BARS, ("imperfection",), {"type": "mode", "amplitude": 0.1, "seed": 3}, "imperfection.seed",
     "does not apply to type = 'mode'"),
    (BARS, ("imperfection",), {"type": "random", "amplitude": -0.1}, "imperfection.amplitude", "> 0"),
    (BARS, ("analysis",), {"type": "dynamics", "dynamics": {"duration": 1.0}}, "analysis.dynamics.time_step",
     "required"),
    (BARS, ("analysis",), {"type": "indentation"}, "analysis.type", "allowed: 'static'"),
    (BARS, ("analysis",), {"merit": "energy", "type": "continuation", "continuation": {"parameter_max": 1.0}},
     "analysis.merit", "applies to 'static'"),
    (BARS, ("gravity",), {"g": [0, 0, -9.81], "h": 1}, "gravity.h", "unknown key"),
])
def test_bad_key_is_named_with_what_is_allowed(base, path, value, key, words):
    with pytest.raises(SceneError) as info:
        parse_scene(_edit(base, path, value))
    assert info.value.key == key
    assert words in str(info.value)


@pytest.mark.parametrize("raw, key, words", [
    ({**LEGACY_NET, "solver": {"schem": "rk4"}}, "solver.schem", "unknown key"),
    ({**LEGACY_NET, "start": {"type": "nurbs", "depth": "deep"}}, "start.depth", "a number"),
    ({**LEGACY_NET, "analysis": {"relaxation": {}}}, "solver", "given twice"),
    ({**LEGACY_NET, "loads": {"gravity": [0, 0, -9.81], "wind": 1}}, "loads.wind", "takes only 'gravity'"),
    ({**LEGACY_NET, "supports": {"groups": ["middle"]}}, "supports.groups", "no node set 'middle'"),
    ({**LEGACY_NET, "supports": {"positions": [[0, 7]]}}, "supports.positions[0]", "out of range"),
    ({**LEGACY_NET, "buckling": {"E": -1.0}}, "buckling.E", "> 0.0"),
])
def test_older_layout_errors_name_the_key_as_written(raw, key, words, tmp_path):
    from shellform.analyses import run_scene

    with pytest.raises(SceneError) as info:
        run_scene(parse_scene(copy.deepcopy(raw)), tmp_path)
    assert info.value.key == key
    if words:
        assert words in str(info.value)


def test_hemisphere_takes_odd_rod_counts_and_force_imperfections_only():
    with pytest.raises(SceneError, match="odd"):
        parse_scene({"geometry": {"type": "hemisphere", "n": 4}})
    with pytest.raises(SceneError, match="only 'forces'"):
        parse_scene({"geometry": {"type": "hemisphere", "n": 5}, "imperfection": {"type": "random", "amplitude": 1.0}})
    with pytest.raises(SceneError, match="pinned on its equator"):
        parse_scene({"geometry": {"type": "hemisphere", "n": 5}, "supports": [{"nodes": [0]}]})


def test_discriminated_table_checks_keys_of_the_chosen_type():
    table = Table(doc="", discriminator="kind", keys={
        "kind": Key("str", "", choices=("a", "b")),
        "x": Key("float", "", default=None, only=("a",), required_for=("a",)),
        "y": Key("float", "", default=2.0, only=("b",)),
    })
    assert check_table("t", {"kind": "a", "x": 1.0}, table) == {"kind": "a", "x": 1.0, "y": 2.0}
    with pytest.raises(SceneError, match="t.x.*required for kind = 'a'"):
        check_table("t", {"kind": "a"}, table)
    with pytest.raises(SceneError, match="t.y.*does not apply to kind = 'a'"):
        check_table("t", {"kind": "a", "x": 1.0, "y": 1.0}, table)


def test_schema_command_documents_every_key_with_unit_and_default(capsys):
    assert main(["schema"]) == 0
    text = capsys.readouterr().out

    def keys(table, path=""):
        for name, spec in table.keys.items():
            if isinstance(spec, Table):
                yield from keys(spec, f"{path}{name}.")
            else:
                yield name, spec

    for name, key in keys(SCENE):
        assert f"| `{name}` | {key.kind} | {key.unit} |" in text, name
    for head in ("[geometry]", "[[supports]]", "[imperfection]", "[analysis.relaxation]", "[analysis.dynamics]",
                 "[analysis.indentation]", "[analysis.buckling]", "[rods]", "[ropes]"):
        assert f"`{head}`" in text, head


def test_scene_file_names_its_own_folder_for_relative_meshes(tmp_path):
    scene = tmp_path / "dome.toml"
    scene.write_text(f"""
[geometry]
type = "file"
file = "{(ROOT / 'meshes' / 'lattice_dome.obj').as_posix()}"
[[members]]
kind = "bar"
EA = 1.0e6
[[supports]]
groups = ["boundary"]
""")
    s = load_scene(scene)
    assert s["name"] == "dome" and s["analysis"]["type"] == "static"
    assert np.array_equal(np.sort(s["mesh"].boundary_nodes()), np.arange(19, 37))


@pytest.mark.parametrize("key, value", [("length_x", 1e300), ("length_y", 2e6)])
def test_absurd_planform_sizes_are_named_before_meshing(key, value):
    """A 1e300 m rectangle once reached the mesher and crashed the interpreter."""
    scene = {"geometry": {"type": "rectangle", "length_x": 2.0, "length_y": 1.0, "n_i": 4, "n_j": 2},
             "supports": [{"groups": ["corners"]}]}
    scene["geometry"][key] = value
    with pytest.raises(SceneError, match=f"geometry.{key}"):
        parse_scene(scene)


def test_a_time_step_far_below_the_duration_is_named():
    try:
        import tomllib
    except ImportError:  # Python 3.10
        import tomli as tomllib

    root = Path(__file__).resolve().parents[1]
    scene = tomllib.loads((root / "scenes" / "chain_dynamics.toml").read_text())
    scene["analysis"]["dynamics"]["time_step"] = 1e-300
    with pytest.raises(SceneError, match="analysis.dynamics.time_step"):
        parse_scene(scene, base_dir=root / "scenes")
