"""Parameter sweeps through Dask's local cluster."""

import json

import pytest

from shellform.cli import main
from shellform.errors import SceneError
from shellform.io.table import read_csv
from shellform.sweep import parse_param, parse_path, set_value
from test_io_and_cli import VON_MISES

pytest.importorskip("dask.distributed")

SCENE = VON_MISES.replace("load_factor = 20.0", "load_factor = 5.0")


def test_sweep_over_four_values_on_a_local_cluster(tmp_path):
    scene = tmp_path / "truss.toml"
    scene.write_text(SCENE)
    out = tmp_path / "sweep"
    code = main(["sweep", str(scene), "--param", "members[0].EA=1e4,2e4,4e4,8e4", "--out", str(out), "--quiet"])
    assert code == 0
    table = read_csv(out / "sweep.csv")
    assert list(table["members[0].EA"]) == [1e4, 2e4, 4e4, 8e4]
    assert all(table["converged"] == 1)
    # deflection under a fixed load halves when the stiffness doubles (small strains)
    d = table["max_displacement"]
    assert d[0] / d[1] == pytest.approx(2.0, rel=0.05)
    assert d[2] / d[3] == pytest.approx(2.0, rel=0.02)
    rows = json.loads((out / "sweep.json").read_text())["rows"]
    assert len(rows) == 4
    assert all((out / r["case"] / "summary.json").exists() for r in rows)
    assert (out / "sweep.png").exists()


def test_key_paths_and_values():
    assert parse_path("members[0].EA") == ["members", 0, "EA"]
    assert parse_param("analysis.merit=energy,residual") == ("analysis.merit", ["energy", "residual"])
    assert parse_param("members[0].slack=0.1, 0.2") == ("members[0].slack", [0.1, 0.2])
    data = {"members": [{"EA": 1.0}]}
    set_value(data, "members[0].EA", 2.0)
    assert data["members"][0]["EA"] == 2.0
    with pytest.raises(SceneError, match="members\\[3\\]"):
        set_value(data, "members[3].EA", 2.0)
    with pytest.raises(SceneError, match="key=v1,v2"):
        parse_param("members[0].EA")


def test_a_bad_value_is_refused_before_anything_runs(tmp_path, capsys):
    scene = tmp_path / "truss.toml"
    scene.write_text(SCENE)
    code = main(["sweep", str(scene), "--param", "members[0].EA=1e4,-1", "--out", str(tmp_path / "s")])
    assert code == 2
    err = capsys.readouterr().err
    assert "members[0].EA" in err and "sweep case" in err


def test_nested_results_are_columns_and_an_unknown_plot_key_is_refused(tmp_path, capsys):
    from shellform.sweep import _scalars

    assert _scalars({"title": "t", "converged": True, "buckling": {"critical_load_factor": 2.5, "events": [1]}}) == {
        "converged": True, "buckling.critical_load_factor": 2.5}
    scene = tmp_path / "truss.toml"
    scene.write_text(SCENE)
    out = tmp_path / "sweep"
    code = main(["sweep", str(scene), "--param", "members[0].EA=1e4,2e4", "--out", str(out), "--quiet",
                 "--plot", "no_such_entry"])
    assert code == 2
    err = capsys.readouterr().err
    assert "no_such_entry" in err and "max_displacement" in err  # the key, and the ones there are
    assert (out / "sweep.csv").exists()  # the work is kept
