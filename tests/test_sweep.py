"""Parameter sweeps: in this process, on a process pool, resumed, with failures as rows, and on Dask."""

import json
import sys

import pytest

from shellform.cli import main
from shellform.errors import SceneError
from shellform.io.table import read_csv
from shellform.studies.sweep import SweepOptions, parse_param, parse_path, run_sweep, scalars, set_value
from shellform.studies.sweep_table import parameter_unit, summary_units
from test_io_and_cli import VON_MISES

SCENE = VON_MISES.replace("load_factor = 20.0", "load_factor = 5.0")


@pytest.fixture
def truss(tmp_path):
    scene = tmp_path / "truss.toml"
    scene.write_text(SCENE)
    return scene


def test_sweep_over_four_values_on_a_process_pool(truss, tmp_path):
    out = tmp_path / "sweep"
    code = main(["sweep", str(truss), "--param", "members[0].EA=1e4,2e4,4e4,8e4", "--out", str(out), "--quiet",
                 "--workers", "2"])
    assert code == 0
    table = read_csv(out / "sweep.csv")
    assert list(table["case"]) == ["case_000", "case_001", "case_002", "case_003"]  # case order, not finish order
    assert list(table["members[0].EA"]) == [1e4, 2e4, 4e4, 8e4]
    assert list(table["status"]) == ["finished"] * 4
    assert all(table["converged"] == 1)
    # deflection under a fixed load halves when the stiffness doubles (small strains)
    d = table["max_displacement"]
    assert d[0] / d[1] == pytest.approx(2.0, rel=0.05)
    assert d[2] / d[3] == pytest.approx(2.0, rel=0.02)
    rows = json.loads((out / "sweep.json").read_text())["rows"]
    assert len(rows) == 4
    assert all((out / r["case"] / "summary.json").exists() for r in rows)
    assert (out / "sweep.png").exists()


def test_local_runs_need_no_dask(truss, tmp_path):
    had_dask = "distributed" in sys.modules
    rows = run_sweep(truss, ["members[0].EA=1e4,2e4"], tmp_path / "s", workers=1)
    assert [r["status"] for r in rows] == ["finished", "finished"]
    if not had_dask:
        assert "distributed" not in sys.modules


def test_the_table_is_written_as_each_case_finishes(truss, tmp_path):
    out = tmp_path / "s"
    seen = []

    def progress(msg):
        if "case_" in msg and (out / "sweep.csv").exists():
            seen.append(len(read_csv(out / "sweep.csv")["case"]))

    run_sweep(truss, ["members[0].EA=1e4,2e4,4e4"], out, workers=1, progress=progress)
    assert seen == [1, 2, 3]  # a sweep killed after a case keeps its row


def test_a_second_run_keeps_finished_cases_and_runs_the_rest(truss, tmp_path):
    out = tmp_path / "s"
    run_sweep(truss, ["members[0].EA=1e4,2e4,4e4"], out, workers=1)
    kept = (out / "case_000" / "summary.json").stat().st_mtime_ns
    # case_001 was killed while running; case_002's folder holds another case (other values)
    s1 = json.loads((out / "case_001" / "summary.json").read_text())
    (out / "case_001" / "summary.json").write_text(json.dumps({**s1, "run_status": "running"}))
    lines = []
    rows = run_sweep(truss, ["members[0].EA=1e4,2e4,3e4,8e4"], out, workers=1, progress=lines.append)
    assert (out / "case_000" / "summary.json").stat().st_mtime_ns == kept
    assert [r["status"] for r in rows] == ["finished"] * 4
    assert json.loads((out / "sweep.json").read_text())["kept"] == ["case_000"]
    assert any("case_000" in m and "kept" in m for m in lines)
    assert not any("case_002" in m and "kept" in m for m in lines)
    table = read_csv(out / "sweep.csv")
    assert list(table["members[0].EA"]) == [1e4, 2e4, 3e4, 8e4]
    assert table["max_displacement"][2] == pytest.approx(table["max_displacement"][0] / 3, rel=0.05)
    # --rerun runs them all again
    rows = run_sweep(truss, ["members[0].EA=1e4,2e4,3e4,8e4"], out, workers=1, rerun=True)
    assert (out / "case_000" / "summary.json").stat().st_mtime_ns != kept
    assert json.loads((out / "sweep.json").read_text())["kept"] == []


def test_a_failing_case_is_a_row_and_the_others_go_on(truss, tmp_path, monkeypatch, capsys):
    import shellform.analyses

    real = shellform.analyses.run_scene

    def run_scene(scene, out_dir, *args, **kwargs):
        if scene["members"][0]["EA"] == 2e4:
            raise RuntimeError("the solver broke down")
        return real(scene, out_dir, *args, **kwargs)

    monkeypatch.setattr(shellform.analyses, "run_scene", run_scene)
    out = tmp_path / "s"
    code = main(["sweep", str(truss), "--param", "members[0].EA=1e4,2e4,4e4", "--out", str(out), "--workers", "1"])
    assert code == 1  # not every case converged
    table = read_csv(out / "sweep.csv")
    assert list(table["status"]) == ["finished", "failed", "finished"]
    assert table["message"][1] == "RuntimeError: the solver broke down"
    assert list(table["converged"]) == [1, 0, 1]
    assert "case_001" in capsys.readouterr().err
    # a failed case is run again by the next sweep into the folder
    monkeypatch.setattr(shellform.analyses, "run_scene", real)
    rows = run_sweep(truss, ["members[0].EA=1e4,2e4,4e4"], out, workers=1)
    assert [r["status"] for r in rows] == ["finished"] * 3
    assert json.loads((out / "sweep.json").read_text())["kept"] == ["case_000", "case_002"]


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
    with pytest.raises(SceneError, match="workers"):
        SweepOptions(workers=0)


def test_a_bad_value_is_refused_before_anything_runs(truss, tmp_path, capsys):
    code = main(["sweep", str(truss), "--param", "members[0].EA=1e4,-1", "--out", str(tmp_path / "s")])
    assert code == 2
    err = capsys.readouterr().err
    assert "members[0].EA" in err and "sweep case" in err
    assert not (tmp_path / "s" / "case_000").exists()


def test_nested_results_are_columns_and_an_unknown_plot_key_is_refused(truss, tmp_path, capsys):
    assert scalars({"title": "t", "converged": True, "buckling": {"critical_load_factor": 2.5, "events": [1]},
                    "units": {"buckling": {"critical_load_factor": "-"}}}) == {
        "converged": True, "buckling.critical_load_factor": 2.5}
    out = tmp_path / "sweep"
    code = main(["sweep", str(truss), "--param", "members[0].EA=1e4,2e4", "--out", str(out), "--quiet",
                 "--workers", "1", "--plot", "no_such_entry"])
    assert code == 2
    err = capsys.readouterr().err
    assert "no_such_entry" in err and "max_displacement" in err  # the key, and the ones there are
    assert (out / "sweep.csv").exists()  # the work is kept


def test_axis_units_come_from_the_scene_reference_and_the_summaries(truss, tmp_path, monkeypatch):
    import shellform.io.table
    import shellform.studies.sweep

    assert parameter_unit("members[0].EA") == "N"
    assert parameter_unit("ropes.slack") == ""  # a coefficient: no unit
    assert parameter_unit("no.such.key") == ""
    assert summary_units({"units": {"max_displacement": "m", "buckling": {"critical_load_factor": ""}}}) == {
        "max_displacement": "m"}
    labels = []
    monkeypatch.setattr(shellform.io.table, "plot_curve", lambda path, x, y, xl, yl, title: labels.append((xl, yl)))
    run_sweep(truss, ["members[0].EA=1e4,2e4"], tmp_path / "a", workers=1)
    assert labels[-1] == ("members[0].EA [N]", "max_displacement")  # the summaries give no unit for it: bare key
    assert read_csv(tmp_path / "a" / "sweep.csv")["members[0].EA"].tolist() == [1e4, 2e4]  # header "... [N]"
    assert (tmp_path / "a" / "sweep.csv").read_text().startswith("case,members[0].EA [N],status,")
    # a summary that gives units: the axis says them
    real = shellform.studies.sweep.run_case
    monkeypatch.setattr(shellform.studies.sweep, "run_case",
                        lambda *args: {**real(*args), "units": {"max_displacement": "m", "iterations": ""}})
    run_sweep(truss, ["members[0].EA=1e4,2e4"], tmp_path / "b", workers=1)
    assert labels[-1] == ("members[0].EA [N]", "max_displacement [m]")


@pytest.mark.slow
def test_critical_load_factor_over_slack_coefficients(tmp_path):
    """The default scene (form finding, then buckling) swept over the ropes' slack: one column, one plot."""
    from shellform.api import builtin_scene_path

    out = tmp_path / "slack"
    code = main(["sweep", str(builtin_scene_path("default")), "--param", "ropes.slack=0.05,0.1,0.2", "--out", str(out),
                 "--quiet", "--workers", "2", "--plot", "buckling.critical_load_factor"])
    assert code == 0
    table = read_csv(out / "sweep.csv")
    lam = table["buckling.critical_load_factor"]
    assert list(table["ropes.slack"]) == [0.05, 0.1, 0.2]
    assert all(lam > 1.0)  # each shell carries the weight it was found for
    assert (out / "sweep.png").exists()


@pytest.mark.slow
def test_sweep_on_a_dask_scheduler(truss, tmp_path):
    distributed = pytest.importorskip("dask.distributed")
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address=None) as c:
        rows = run_sweep(truss, ["members[0].EA=1e4,2e4"], tmp_path / "d", scheduler=c.scheduler_address)
    assert [r["status"] for r in rows] == ["finished", "finished"]
