"""Property-based tests: malformed and extreme scenes give a named error or a valid run."""

import copy
import json
import math

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from shellform.errors import SceneError
from shellform.pipeline import run_scene
from shellform.scene import parse_scene

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


_DELETE = object()


def no_nan(obj):
    if isinstance(obj, float):
        return math.isfinite(obj)
    if isinstance(obj, dict):
        return all(no_nan(v) for v in obj.values())
    if isinstance(obj, list):
        return all(no_nan(v) for v in obj)
    return True


def check(scene, tmp_path):
    try:
        parsed = parse_scene(scene)
        summary = run_scene(parsed, tmp_path)
    except SceneError as exc:
        assert exc.key and exc.problem  # names the key and the problem
        return
    written = json.loads((tmp_path / "summary.json").read_text())
    assert no_nan(written), written
    assert isinstance(summary["converged"], bool)


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
