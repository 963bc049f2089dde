"""The system evaluates exactly the effects a scene lists: counted, not assumed."""

from collections import Counter

import pytest

from shellform.effects import AxialBar, ConstantForce, Rope
from shellform.analyses import run_scene
from shellform.scene import parse_scene

SCENE = {
    "nodes": {"coordinates": [[-1.0, 0.0, 0.0], [0.0, 0.0, 0.2], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]},
    "members": [
        {"kind": "bar", "connectivity": [[0, 1], [1, 2]], "EA": 1.0e4, "mass_per_length": 1.0},
        {"kind": "rope", "connectivity": [[1, 3]], "EA": 1.0e3, "slack": 0.5},
    ],
    "supports": [{"nodes": [0, 2, 3]}, {"nodes": [1], "dofs": "y"}],
    "loads": [{"nodes": [1], "force": [0.0, 0.0, -1.0]}],
    "gravity": {},
    "analysis": {"load_factor": 5.0},
}


@pytest.fixture
def calls(monkeypatch):
    counter = Counter()
    for cls in (AxialBar, Rope, ConstantForce):
        for method in ("energy", "gradient", "hessian_values"):
            original = getattr(cls, method)

            def counted(self, q, _original=original, _key=(cls.__name__, method)):
                counter[_key[0] if not isinstance(self, ConstantForce) else self.name] += 1
                return _original(self, q)

            monkeypatch.setattr(cls, method, counted)
    return counter


@pytest.mark.parametrize("include, evaluated, never", [
    (None, {"AxialBar", "Rope", "loads", "gravity"}, set()),
    (["axial", "loads"], {"AxialBar", "loads"}, {"Rope", "gravity"}),
    (["axial", "rope"], {"AxialBar", "Rope"}, {"loads", "gravity"}),
])
def test_only_listed_effects_are_evaluated(calls, tmp_path, include, evaluated, never):
    scene = dict(SCENE)
    if include is not None:
        scene["effects"] = {"include": include}
    summary = run_scene(parse_scene(scene), tmp_path)
    assert summary["converged"] is True
    assert {k for k, v in calls.items() if v > 0} == evaluated
    assert all(calls[k] == 0 for k in never)
