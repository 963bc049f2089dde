"""Export (read back with meshio), scenes and the shellform command end to end."""

import json
import subprocess
import sys
from pathlib import Path

import meshio
import numpy as np
import pytest

import shellform as sf
from shellform.cli import main
from shellform.errors import SceneError
from shellform.io import write_series, write_state
from shellform.scene import build_structure, load_scene, parse_scene, scene_system

VON_MISES = """
title = "von Mises truss"
[nodes]
coordinates = [[-1.0, 0.0, 0.0], [0.0, 0.0, 0.2], [1.0, 0.0, 0.0]]
[[members]]
kind = "bar"
connectivity = [[0, 1], [1, 2]]
EA = 1.0e4
[[supports]]
nodes = [0, 2]
[[supports]]
nodes = [1]
dofs = "y"
[[loads]]
nodes = [1]
force = [0.0, 0.0, -1.0]
[analysis]
load_factor = 20.0
"""


def solved_net():
    s = sf.Structure([[0, 0, 0], [1, 0, 0], [2, 0, 0], [1, 1, 0]])
    s.add_ropes([[0, 1], [1, 2], [1, 3]], EA=1e3, slack=0.05, mass_per_length=1.0, name="net")
    s.add_bars([[0, 3], [3, 2]], EA=1e4, name="frame")
    s.fix([0, 2, 3])
    s.set_gravity()
    system = sf.build_system(s)
    res = sf.solve_static(system)
    assert res.success, res.message
    return system, res


def test_a_result_no_member_computes_is_not_written(tmp_path):
    s = sf.Structure([[0, 0, 0], [1, 0, 0]])
    s.add_bars([[0, 1]], EA=1e3)
    s.fix([0])
    s.fix([1], "yz")
    system = sf.build_system(s)
    mesh = meshio.read(write_state(tmp_path / "bar.vtu", system, system.q_ref))
    assert "slack" not in mesh.cell_data and "axial_force" in mesh.cell_data


def test_state_round_trip_through_vtu(tmp_path):
    system, res = solved_net()
    path = write_state(tmp_path / "state.vtu", system, res.q)
    mesh = meshio.read(path)
    n = system.structure.n_nodes
    assert np.allclose(mesh.points, res.q.reshape(n, 3))
    assert np.allclose(mesh.point_data["displacement"], res.q.reshape(n, 3) - system.structure.nodes)
    assert np.allclose(mesh.point_data["reaction"], res.reactions.reshape(n, 3))
    forces = system.member_results(res.q)
    expected = np.concatenate([forces["net"]["axial_force"], forces["frame"]["axial_force"]])
    assert np.allclose(mesh.cell_data["axial_force"][0], expected)
    # bars are never slack: their slack is not computed, so it is absent (NaN), not a taut 0
    slack = mesh.cell_data["slack"][0]
    assert list(slack[:3]) == list(forces["net"]["slack"]) and np.all(np.isnan(slack[3:]))
    assert list(mesh.cell_data["group"][0]) == [0, 0, 0, 1, 1]
    assert not list(tmp_path.glob(".state-*")), "temporary file left behind"


def test_series_round_trip_through_xdmf(tmp_path):
    system, res = solved_net()
    states = [(t, system.q_ref + t * (res.q - system.q_ref), 1.0) for t in (0.0, 0.5, 1.0)]
    path = write_series(tmp_path / "path.xdmf", system, states)
    with meshio.xdmf.TimeSeriesReader(path) as reader:
        points, cells = reader.read_points_cells()
        assert reader.num_steps == 3
        assert np.allclose(points, system.structure.nodes)
        for k, (t, q, _) in enumerate(states):
            time, point_data, cell_data = reader.read_data(k)
            assert time == pytest.approx(t)
            assert np.allclose(point_data["displacement"], (q - system.q_ref).reshape(-1, 3))
            assert np.all(np.isfinite(cell_data["axial_force"][0]))


def test_scene_builds_only_the_listed_effects():
    scene = parse_scene(__import__("tomllib").loads(VON_MISES))
    structure = build_structure(scene)
    system = scene_system(scene, structure)
    assert [e.name for e in system.effects] == ["axial", "loads"]
    scene["effects"] = {"include": ["axial"]}
    assert [e.name for e in scene_system(scene, structure).effects] == ["axial"]


@pytest.mark.parametrize(
    "edit, key, words",
    [
        (lambda t: t.replace("EA = 1.0e4", "EA = -5.0"), "members[0].EA", "> 0.0"),
        (lambda t: t.replace("EA = 1.0e4", 'EA = "stiff"'), "members[0].EA", "a number"),
        (lambda t: t.replace("kind = \"bar\"", "kind = \"beam\""), "members[0].kind", "'bar', 'rope'"),
        (lambda t: t.replace("connectivity = [[0, 1], [1, 2]]", "connectivity = [[0, 1], [1, 5]]"),
         "members[0]", "node index 5 is out of range"),
        (lambda t: t.replace("[[0, 1], [1, 2]]", "[[0, 1], [1, 2, 3]]"), "members[0].connectivity", "node pairs"),
        (lambda t: t.replace("dofs = \"y\"", "dofs = \"w\""), "supports[1]", "x, y, z"),
        (lambda t: t.replace("load_factor", "load_fcator"), "analysis.load_fcator", "unknown key"),
        (lambda t: t.replace("[0.0, 0.0, 0.2]", "[0.0, nan, 0.2]"), "nodes.coordinates[1, 1]", "not finite"),
        (lambda t: t.replace("[[supports]]\nnodes = [0, 2]\n", ""), "supports", "translate freely"),
        (lambda t: t.replace("[nodes]", "[nodez]"), "nodez", "unknown key"),
    ],
)
def test_malformed_scene_names_the_key(tmp_path, edit, key, words):
    path = tmp_path / "bad.toml"
    path.write_text(edit(VON_MISES))
    with pytest.raises(SceneError) as info:
        scene = load_scene(path)
        scene_system(scene, build_structure(scene))
    assert info.value.key.replace(" ", "") == key.replace(" ", "")
    assert words in str(info.value)


def test_not_toml_is_reported(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text("[nodes\ncoordinates = 3")
    with pytest.raises(SceneError, match="not valid TOML"):
        load_scene(path)


def test_run_writes_summary_and_meshes(tmp_path):
    scene = tmp_path / "truss.toml"
    scene.write_text(VON_MISES)
    out = tmp_path / "out"
    assert main(["run", str(scene), "--out", str(out), "--quiet"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    for key in ("converged", "iterations", "residual_norm", "n_nodes", "n_members", "n_dof", "wall_time_s"):
        assert key in summary
    assert summary["converged"] is True
    assert (summary["n_nodes"], summary["n_members"], summary["n_dof"]) == (3, 2, 9)
    assert summary["reaction_sum"][2] == pytest.approx(20.0, rel=1e-8)
    mesh = meshio.read(out / "state.vtu")
    assert len(mesh.points) == 3
    assert (out / "state.xdmf").exists()


def test_command_line_reports_scene_errors_without_traceback(tmp_path):
    scene = tmp_path / "bad.toml"
    scene.write_text(VON_MISES.replace("EA = 1.0e4", "EA = 0.0"))
    proc = subprocess.run(
        [sys.executable, "-m", "shellform", "run", str(scene), "--out", str(tmp_path / "o")],
        capture_output=True, text=True,
    )
    assert proc.returncode == 2
    assert "scene key 'members[0].EA'" in proc.stderr
    assert "Traceback" not in proc.stderr


def test_default_scene_finds_a_form_and_its_first_critical_point(tmp_path):
    assert main(["run", "--out", str(tmp_path), "--quiet"]) == 0
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["converged"]
    assert summary["n_taut_ropes"] > summary["n_slack_ropes"]
    assert summary["buckling"]["critical_load_factor"] > 0
    assert summary["buckling"]["critical_kind"] in ("limit", "bifurcation")
    for name in ("hanging.vtu", "inverted.vtu", "buckling_path.csv", "buckling_curve.png"):
        assert (tmp_path / name).exists(), name


def test_scene_reference_in_docs_matches_the_schema(capsys):
    assert main(["schema"]) == 0
    generated = capsys.readouterr().out.strip()
    docs = (Path(__file__).parents[1] / "docs" / "scenes.md").read_text()
    assert generated in docs, "docs/scenes.md is out of date: paste the output of `shellform schema`"


CONTINUATION = VON_MISES.replace(
    "[analysis]\nload_factor = 20.0\n",
    "[analysis]\ntype = \"continuation\"\n[analysis.continuation]\ncontrol = \"load\"\n"
    "parameter_max = 40.0\nmax_displacement = 0.5\nmonitor_node = 1\nmax_steps = 60\n",
)


def test_continuation_scene_writes_path_events_and_plot(tmp_path):
    from shellform.io.table import read_csv

    scene = tmp_path / "path.toml"
    scene.write_text(CONTINUATION)
    out = tmp_path / "out"
    assert main(["run", str(scene), "--out", str(out), "--quiet"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    alpha = np.arctan(0.2)
    p_cr = 2 * 1.0e4 * np.sin(np.arccos(np.cos(alpha) ** (1 / 3))) ** 3
    limits = [e["load"] for e in summary["events"] if e["kind"] == "limit"]
    assert limits and limits[0] == pytest.approx(p_cr, rel=5e-3)
    table = read_csv(out / "path.csv")
    assert {"step", "lam", "n_negative", "iterations", "uz1"} <= set(table)
    assert len(table["step"]) == summary["points"]
    assert table["n_negative"].max() == 1  # the descending branch is unstable
    with meshio.xdmf.TimeSeriesReader(out / "path.xdmf") as reader:
        reader.read_points_cells()
        assert reader.num_steps == summary["points"]
    assert (out / "load_displacement.png").stat().st_size > 1000


@pytest.mark.parametrize("critical_rtol", [1e-2, 1e-6, 1e-10])
def test_the_scene_sets_the_tolerance_of_the_critical_load(tmp_path, critical_rtol):
    scene = tmp_path / "path.toml"
    scene.write_text(CONTINUATION + f"critical_rtol = {critical_rtol!r}\n")
    assert main(["run", str(scene), "--out", str(tmp_path / "out"), "--quiet"]) == 0
    limit = [e for e in json.loads((tmp_path / "out" / "summary.json").read_text())["events"]
             if e["kind"] == "limit"][0]
    alpha = np.arctan(0.2)
    p_cr = 2 * 1.0e4 * np.sin(np.arccos(np.cos(alpha) ** (1 / 3))) ** 3
    assert limit["located"] and abs(limit["load"] - p_cr) <= critical_rtol * p_cr


@pytest.mark.parametrize("load, warned", [(-1.0, False), (-100.0, True)])
def test_a_structure_buckling_below_its_loads_is_flagged(tmp_path, capsys, load, warned):
    # the truss snaps at 29.6 N: under 100 N the first limit point is at load factor 0.296
    scene = tmp_path / "path.toml"
    scene.write_text(CONTINUATION.replace("force = [0.0, 0.0, -1.0]", f"force = [0.0, 0.0, {load!r}]")
                     .replace("parameter_max = 40.0", f"parameter_max = {40.0 / abs(load)!r}"))
    assert main(["run", str(scene), "--out", str(tmp_path / "out")]) == 0
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    notes = [w for w in summary.get("warnings", []) if "less than the loads themselves" in w]
    assert len(notes) == warned
    if warned:
        alpha = np.arctan(0.2)
        p_cr = 2 * 1.0e4 * np.sin(np.arccos(np.cos(alpha) ** (1 / 3))) ** 3
        assert f"load factor {p_cr / 100:.4g} < 1" in notes[0]
        assert capsys.readouterr().err.count("less than the loads themselves") == 1
        assert "less than the loads themselves" in (tmp_path / "out" / "run.log").read_text()


def test_interrupted_continuation_resumes_from_its_checkpoint(tmp_path):
    from shellform.io.table import read_csv

    full, part = tmp_path / "full.toml", tmp_path / "part.toml"
    full.write_text(CONTINUATION.replace("checkpoint_every", "x"))
    part.write_text(CONTINUATION.replace("max_steps = 60", "max_steps = 6\ncheckpoint_every = 2"))
    assert main(["run", str(full), "--out", str(tmp_path / "a"), "--quiet"]) == 0
    assert main(["run", str(part), "--out", str(tmp_path / "b"), "--quiet"]) == 0
    assert len(read_csv(tmp_path / "b" / "path.csv")["step"]) == 7
    # the same scene with the full step budget, resumed where the short run stopped
    part.write_text(CONTINUATION.replace("max_steps = 60", "max_steps = 60\ncheckpoint_every = 2"))
    assert main(["run", str(part), "--out", str(tmp_path / "b"), "--quiet", "--resume"]) == 0
    a, b = read_csv(tmp_path / "a" / "path.csv"), read_csv(tmp_path / "b" / "path.csv")
    assert len(a["step"]) == len(b["step"])
    assert np.allclose(a["lam"], b["lam"], rtol=1e-8, atol=1e-10)


def test_version_is_printed(capsys):
    from shellform import __version__
    from shellform.cli import main

    with pytest.raises(SystemExit) as info:
        main(["--version"])
    assert info.value.code == 0 and capsys.readouterr().out.strip() == f"shellform {__version__}"
