"""Every scene shipped with shellform runs end to end and its outputs read back."""

import json

import meshio
import pytest
from helpers import all_finite

from shellform.cli import builtin_scenes, main
from shellform.io.table import read_csv


@pytest.mark.parametrize("name", builtin_scenes())
def test_builtin_scene_runs_and_outputs_read_back(name, tmp_path):
    assert main(["run", name, "--out", str(tmp_path), "--quiet"]) == 0
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["converged"] is True
    assert all_finite(summary)
    for name in summary.get("files", []):
        path = tmp_path / name
        assert path.exists(), name
        if path.suffix == ".vtu":
            assert len(meshio.read(path).points) == summary["n_nodes"]
        elif path.suffix == ".xdmf":
            with meshio.xdmf.TimeSeriesReader(path) as reader:
                points, _ = reader.read_points_cells()
                assert reader.num_steps >= 1
        elif path.suffix == ".csv":
            assert len(next(iter(read_csv(path).values()))) >= 1


def test_default_scene_is_listed():
    assert "default" in builtin_scenes()
