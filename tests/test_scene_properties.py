"""Property-based tests: malformed and extreme scenes give a named error or a valid run.

One base scene per kind (bars node by node, a hanging net on a planform, a mesh file,
time stepping, the hemisphere); any value replaced by anything, or any key deleted, must
end in a SceneError that names a key and the problem, or in a run whose summary is
clean JSON. The hemisphere is only parsed (a run takes seconds).
"""

import copy
import json
from pathlib import Path

import pytest
from helpers import all_finite
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from shellform.errors import SceneError
from shellform.analyses import run_scene
from shellform.scene import parse_scene

ROOT = Path(__file__).resolve().parents[1]

BASE = {
    "title": "two-bar truss",
    "nodes": {"coordinates": [[-1.0, 0.0, 0.0], [0.0, 0.0, 0.2], [1.0, 0.0, 0.0]]},
    "members": [{"kind": "bar", "connectivity": [[0, 1], [1, 2]], "EA": 1.0e4, "mass_per_length": 1.0}],
    "supports": [{"nodes": [0, 2], "dofs": "xyz"}, {"nodes": [1], "dofs": "y"}],
    "loads": [{"nodes": [1], "force": [0.0, 0.0, -1.0]}],
    "gravity": {"g": [0.0, 0.0, -9.81]},
    "analysis": {"type": "static", "load_factor": 5.0, "max_iterations": 30},
}

# every place a value can be replaced: (path into the scene)
PATHS = [
    ("title",), ("nodes", "coordinates"), ("nodes", "coordinates", 1), ("nodes", "coordinates", 1, 2),
    ("members", 0, "kind"), ("members", 0, "connectivity"), ("members", 0, "connectivity", 1),
    ("members", 0, "connectivity", 1, 0), ("members", 0, "EA"), ("members", 0, "mass_per_length"),
    ("supports", 0, "nodes"), ("supports", 1, "dofs"), ("loads", 0, "force"), ("loads", 0, "nodes"),
    ("loads", 0, "scaled"), ("gravity", "g"), ("analysis", "type"), ("analysis", "load_factor"),
    ("analysis", "max_iterations"), ("analysis", "merit"), ("analysis", "rtol"),
]

NET = {
    "title": "hanging net",
    "geometry": {"type": "rectangle", "length_x": 2.0, "length_y": 1.0, "n_i": 4, "n_j": 2},
    "supports": [{"groups": ["corners"]}],
    "ropes": {"slack": 0.05, "mass_per_length": 1.0},
    "analysis": {"type": "mra", "relaxation": {"max_iterations": 200, "checkpoint_interval": 0.0},
                 "start_shape": {"type": "flat"}},
    "output": {"meshes": True, "formats": ["vtu"]},
}
NET_PATHS = [
    ("geometry", "type"), ("geometry", "length_x"), ("geometry", "n_i"), ("geometry", "n_j"),
    ("supports", 0, "groups"), ("supports", 0, "groups", 0), ("supports", 0), ("ropes", "slack"),
    ("ropes", "mass_per_length"), ("analysis", "type"), ("analysis", "relaxation", "scheme"),
    ("analysis", "relaxation", "max_iterations"), ("analysis", "relaxation", "checkpoint_interval"),
    ("analysis", "start_shape", "type"), ("output", "meshes"), ("output", "formats"),
]

MESH = {
    "title": "lattice dome",
    "geometry": {"type": "file", "file": "meshes/lattice_dome.obj"},
    "members": [{"kind": "bar", "EA": 2.0e6, "cells": ["triangle"]}],
    "supports": [{"z": 0.0}],
    "loads": [{"nodes": [0], "force": [0.0, 0.0, -100.0]}],
    "imperfection": {"type": "random", "amplitude": 0.001, "seed": 1},
    "analysis": {"type": "static", "max_iterations": 30},
}
MESH_PATHS = [
    ("geometry", "file"), ("members", 0, "cells"), ("members", 0, "cells", 0), ("members", 0, "connectivity"),
    ("supports", 0, "z"), ("supports", 0, "z_tolerance"), ("supports", 0, "groups"), ("imperfection", "type"),
    ("imperfection", "amplitude"), ("imperfection", "seed"), ("imperfection", "load_factor"),
]

DYNAMICS = copy.deepcopy(BASE)
DYNAMICS["analysis"] = {"type": "dynamics", "load_factor": 5.0,
                        "dynamics": {"time_step": 0.01, "duration": 0.05, "damping": 1.0, "output_every": 2,
                                     "monitor_node": 1}}
DYNAMICS_PATHS = [("analysis", "dynamics", k) for k in
                  ("time_step", "duration", "damping", "output_every", "monitor_node", "monitor_component",
                   "ramp_time", "checkpoint_interval")]

HEMISPHERE = {
    "geometry": {"type": "hemisphere", "n": 5, "voronoi_length": 4.0e-3},
    "rods": {"radius": 1.0e-3, "E": 1.0e11, "joints": "penalty"},
    "imperfection": {"type": "forces", "amplitude": 5e-3},
    "analysis": {"type": "indentation", "indentation": {"mode": "II", "max_displacement": 1.0}},
}
HEMISPHERE_PATHS = [
    ("geometry", "n"), ("geometry", "voronoi_length"), ("geometry", "radius"), ("rods", "radius"),
    ("rods", "E"), ("rods", "joints"), ("rods", "rest_shape"), ("imperfection", "type"),
    ("imperfection", "amplitude"), ("analysis", "indentation", "mode"),
    ("analysis", "indentation", "max_displacement"), ("analysis", "type"), ("supports",), ("members",),
]

weird = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(min_value=-10**12, max_value=10**12),
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([0.0, -0.0, 1e-300, 1e300, -1.0, 3, 2.5, float("nan"), float("inf")]),
    st.text(max_size=8),
    st.lists(st.floats(allow_nan=True, allow_infinity=True, width=32), max_size=4),
    st.lists(st.lists(st.integers(-3, 5), max_size=3), max_size=3),
    st.dictionaries(st.text(max_size=4), st.integers(), max_size=2),
)

_DELETE = object()


def replace(scene, path, value):
    scene = copy.deepcopy(scene)
    node = scene
    for key in path[:-1]:
        node = node[key]
    if value is _DELETE:
        if isinstance(node, dict):
            node.pop(path[-1], None)
        else:
            del node[path[-1]]
    else:
        node[path[-1]] = value
    return scene


def check(scene, tmp_path, run=True):
    try:
        parsed = parse_scene(scene, base_dir=ROOT)
        if not run:
            return
        summary = run_scene(parsed, tmp_path)
    except SceneError as exc:
        assert exc.key and exc.problem  # names the key and the problem
        return
    written = json.loads((tmp_path / "summary.json").read_text())
    assert all_finite(written), written
    assert isinstance(summary["converged"], bool)


def test_the_base_scenes_are_valid(tmp_path):
    for base in (BASE, NET, MESH, DYNAMICS):
        summary = run_scene(parse_scene(base, base_dir=ROOT), tmp_path)
        assert summary["converged"] is True, base["title"]
    assert parse_scene(HEMISPHERE)["analysis"]["type"] == "indentation"


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(path=st.sampled_from(PATHS), value=weird)
def test_any_replaced_value_gives_a_named_error_or_a_clean_run(tmp_path, path, value):
    check(replace(BASE, path, value), tmp_path)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(path=st.sampled_from(PATHS))
def test_any_deleted_key_gives_a_named_error_or_a_clean_run(tmp_path, path):
    check(replace(BASE, path, _DELETE), tmp_path)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(scale=st.floats(min_value=-300, max_value=300), ea=st.floats(min_value=-300, max_value=300))
def test_extreme_magnitudes_run_cleanly(tmp_path, scale, ea):
    scene = copy.deepcopy(BASE)
    scene["analysis"]["load_factor"] = 10.0**scale if abs(scale) < 300 else 1.0
    scene["members"][0]["EA"] = 10.0 ** ea if abs(ea) < 300 else 1.0
    check(scene, tmp_path)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(path=st.sampled_from(NET_PATHS), value=st.one_of(weird, st.just(_DELETE)))
def test_form_finding_scene_with_any_value_replaced(tmp_path, path, value):
    check(replace(NET, path, value), tmp_path)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(path=st.sampled_from(MESH_PATHS), value=st.one_of(weird, st.just(_DELETE)))
def test_mesh_file_scene_with_any_value_replaced(tmp_path, path, value):
    check(replace(MESH, path, value), tmp_path)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(path=st.sampled_from(DYNAMICS_PATHS), value=st.one_of(weird, st.just(_DELETE)))
def test_dynamics_scene_with_any_value_replaced(tmp_path, path, value):
    scene = replace(DYNAMICS, path, value)
    d = scene["analysis"]["dynamics"]
    h, t = d.get("time_step", 0.01), d.get("duration", 0.05)
    numbers = all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in (h, t))
    if numbers and h > 0 and t / h > 1000:
        return  # a valid but long integration: not what this test is about
    check(scene, tmp_path)


@settings(max_examples=80, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(path=st.sampled_from(HEMISPHERE_PATHS), value=st.one_of(weird, st.just(_DELETE)))
def test_hemisphere_scene_with_any_value_replaced_parses_or_names_the_key(tmp_path, path, value):
    check(replace(HEMISPHERE, path, value), tmp_path, run=False)


# entries of number arrays in BASE and the key each is reported under
ENTRIES = {
    ("nodes", "coordinates", 1, 2): "nodes.coordinates[1, 2]",
    ("members", 0, "connectivity", 1, 0): "members[0].connectivity[1, 0]",
    ("loads", 0, "force", 1): "loads[0].force[1]",
    ("loads", 0, "nodes", 0): "loads[0].nodes[0]",
    ("supports", 0, "nodes", 1): "supports[0].nodes[1]",
    ("gravity", "g", 0): "gravity.g[0]",
}


@settings(max_examples=60, deadline=None)
@given(path=st.sampled_from(sorted(ENTRIES)), value=st.one_of(
    st.booleans(), st.text(max_size=5), st.sampled_from(["0.5", "1", "nan", "1e3"]), st.none(),
    st.lists(st.integers(), max_size=2), st.dictionaries(st.text(max_size=2), st.integers(), max_size=1)))
def test_a_non_number_inside_a_number_array_is_named_never_coerced(path, value):
    with pytest.raises(SceneError) as info:
        parse_scene(replace(BASE, path, value))
    assert info.value.key == ENTRIES[path]
    assert "expected" in info.value.problem


@settings(max_examples=60, deadline=None)
@given(path=st.sampled_from(sorted(ENTRIES)), exponent=st.integers(14, 308), sign=st.sampled_from([1, -1]))
def test_a_number_of_absurd_magnitude_is_named_where_it_stands(path, exponent, sign):
    # beyond every bound (1e6 m, 1e12 N, 1e9 for node numbers); node numbers are integers
    value = sign * 10**exponent if path[-2] in ("connectivity", "nodes") or path[-3:-1] == ("connectivity", 1) \
        else sign * 10.0**exponent
    with pytest.raises(SceneError) as info:
        parse_scene(replace(BASE, path, value))
    assert info.value.key == ENTRIES[path]
    assert "magnitude" in info.value.problem or "expected" in info.value.problem
