"""Every example scene in scenes/ through the command line, its outputs read back.

Each scene runs once (module fixture); the tests read its files back with meshio,
rhino3dm, the CSV reader and json and check them against the physics.
"""

import json
from pathlib import Path

import meshio
import numpy as np
import pytest
from helpers import all_finite

from shellform.cli import main
from shellform.errors import SceneError
from shellform.io.mesh_import import read_mesh
from shellform.io.table import read_csv
from shellform.scene import build_model, load_scene, parse_scene
from shellform.solvers import solve_static
from shellform.solvers.continuation import trace_path

ROOT = Path(__file__).resolve().parents[1]
SCENES = ROOT / "scenes"


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    done = {}

    def go(name):
        if name not in done:
            out = tmp_path_factory.mktemp(name)
            code = main(["run", str(SCENES / f"{name}.toml"), "--out", str(out), "--quiet"])
            summary = json.loads((out / "summary.json").read_text())
            done[name] = (code, out, summary)
        return done[name]

    return go


def test_every_example_is_covered():
    assert sorted(p.stem for p in SCENES.glob("*.toml")) == sorted(EXAMPLES)


EXAMPLES = ["lattice_dome", "lattice_dome_imperfect", "chain_dynamics", "hemisphere_indentation", "barrel_vault",
            "l_shape", "l_shape_gridshell", "courtyard", "cable_net", "rod_gridshell", "form_found_gridshell"]


@pytest.mark.parametrize("name", EXAMPLES)
def test_example_runs_and_lists_its_files(run, name):
    code, out, summary = run(name)
    assert code == 0 and summary["converged"] is True
    assert all_finite(summary)
    for f in summary["files"]:
        assert (out / f).exists(), f
    assert not list(out.glob(".*")), "temporary file left behind"


def test_mesh_file_dome_carries_its_load_and_weight(run):
    rhino3dm = pytest.importorskip("rhino3dm")
    code, out, summary = run("lattice_dome")
    mesh = read_mesh(ROOT / "meshes" / "lattice_dome.obj")
    edges = mesh.edges()
    assert (summary["n_nodes"], summary["n_members"]) == (37, 90) == (len(mesh.points), len(edges))
    length = np.linalg.norm(mesh.points[edges[:, 0]] - mesh.points[edges[:, 1]], axis=1).sum()
    # the rim reactions carry the apex load and the bars' weight (2 kg/m)
    assert summary["reaction_sum"][2] == pytest.approx(500.0 + 2.0 * 9.81 * length, rel=1e-9)
    state = meshio.read(out / "state.vtu")
    assert len(state.points) == 37 and len(state.cells_dict["line"]) == 90
    rim = np.abs(mesh.points[:, 2]) < 1e-9
    assert np.allclose(state.point_data["displacement"][rim], 0.0)
    assert np.all(np.abs(state.point_data["displacement"][~rim]).max(axis=1) > 0)
    model = rhino3dm.File3dm.Read(str(out / "state.3dm"))
    layers = {layer.Index: layer.FullPath for layer in model.Layers}
    on = [layers[o.Attributes.LayerIndex] for o in model.Objects]
    assert on.count("members::bars") == 90 and on.count("supports") == int(rim.sum())


def test_mode_imperfection_lowers_the_snap_load(run):
    code, out, summary = run("lattice_dome_imperfect")
    table = read_csv(out / "path.csv")
    assert len(table["step"]) == summary["points"]
    assert {"lam", "n_negative", "uz0"} <= set(table)
    limits = [e["load"] for e in summary["events"] if e["kind"] == "limit"]
    assert limits and table["n_negative"].max() >= 1
    assert summary["imperfection"]["type"] == "mode"
    assert summary["imperfection"]["max_node_movement_m"] == pytest.approx(0.01, rel=1e-12)
    # the perfect dome, traced the same way, snaps at a higher load
    scene = load_scene(SCENES / "lattice_dome_imperfect.toml")
    scene["imperfection"] = None
    perfect = build_model(scene)
    c = scene["analysis"]["continuation"]
    res = trace_path(perfect.system, "load", parameter_bounds=(None, c["parameter_max"]),
                     max_displacement=c["max_displacement"], max_steps=c["max_steps"])
    perfect_limit = next(e.load for e in res.events if e.kind == "limit")
    assert limits[0] < 0.5 * perfect_limit
    with meshio.xdmf.TimeSeriesReader(out / "path.xdmf") as reader:
        reader.read_points_cells()
        assert reader.num_steps == summary["points"]


def test_chain_swings_into_its_hanging_shape(run):
    code, out, summary = run("chain_dynamics")
    table = read_csv(out / "dynamics.csv")
    assert list(table["step"]) == list(range(summary["steps"] + 1))
    assert table["time"][-1] == pytest.approx(3.0)
    ke = table["kinetic_energy"]
    assert ke[0] == 0.0 and ke[-1] < 1e-3 * ke.max()  # damped out
    with meshio.xdmf.TimeSeriesReader(out / "dynamics.xdmf") as reader:
        reader.read_points_cells()
        assert reader.num_steps == summary["frames"]
        t, point_data, _ = reader.read_data(reader.num_steps - 1)
        assert t == pytest.approx(3.0)
    # at rest in the static equilibrium of the same chain
    scene = load_scene(SCENES / "chain_dynamics.toml")
    static = solve_static(build_model(scene).system)
    final = meshio.read(out / "state.vtu").points
    assert np.abs(final - static.q.reshape(-1, 3)).max() < 2e-3
    assert table["uz5"][-1] == pytest.approx(static.q[3 * 5 + 2], abs=2e-3)


def test_hemisphere_snaps_near_the_published_thresholds(run):
    code, out, summary = run("hemisphere_indentation")
    # the gridshell paper, mode I: 1.1, 1.7, 1.9 (dD/R), tolerance 0.1 (shellform.gridshell.study.PUBLISHED)
    assert len(summary["thresholds_dD_over_R"]) == 3
    assert np.allclose(summary["thresholds_dD_over_R"], [1.1, 1.7, 1.9], atol=0.1)
    table = read_csv(out / "indentation.csv")
    assert table["dD_over_R"][0] == 0.0 and table["dD_over_R"][-1] == pytest.approx(2.0)
    assert np.allclose(table["force_normalised"], table["force"] / summary["force_scale_N"])
    assert np.all(table["n_negative"] == 0)  # only stable states are on the quasi-static path
    with meshio.xdmf.TimeSeriesReader(out / "indentation.xdmf") as reader:
        points, _ = reader.read_points_cells()
        assert reader.num_steps == len(table["dD"]) and len(points) == summary["n_nodes"]
    confs = summary["configurations"]
    assert confs[0]["dD_over_R"] == 0.0 and confs[0]["label"] == "U+"
    for c in confs:
        mesh = meshio.read(out / c["file"])
        assert len(mesh.points) == summary["n_nodes"]
    apex = meshio.read(out / confs[-1]["file"]).points[:, 2].max()
    assert apex < meshio.read(out / confs[0]["file"]).points[:, 2].max()


def test_found_form_exports_read_back(run):
    rhino3dm = pytest.importorskip("rhino3dm")
    code, out, summary = run("barrel_vault")
    assert summary["all_ropes_taut"] is True  # MRA paper, Fig. 3
    shell = meshio.read(out / "inverted_shell.vtu")
    assert list(shell.cells_dict) == ["quad"] and len(shell.cells_dict["quad"]) == 36
    inverted = meshio.read(out / "inverted.vtu")
    hanging = meshio.read(out / "hanging.vtu")
    assert np.allclose(shell.points, inverted.points)
    assert np.allclose(shell.points[:, :2], hanging.points[:, :2])
    assert np.allclose(shell.point_data["height"], shell.points[:, 2] - shell.points[shell.point_data["support"] > 0, 2].max())
    assert shell.point_data["height"].max() == pytest.approx(summary["rise"], rel=1e-9)
    assert np.all(shell.cell_data["area"][0] > 0)
    model = rhino3dm.File3dm.Read(str(out / "form.3dm"))
    layers = {layer.Index: layer.Name for layer in model.Layers}
    by_layer = {}
    for obj in model.Objects:
        by_layer.setdefault(layers[obj.Attributes.LayerIndex], []).append(obj.Geometry)
    assert len(by_layer["hanging net"]) == len(by_layer["inverted net"]) == summary["n_ropes"]
    assert len(by_layer["centrelines"]) == 5 + 10  # grid lines of a 9 x 4 grid
    (surface,) = by_layer["inverted shell"]
    assert len(surface.Faces) == 36 and len(surface.Vertices) == len(shell.points)
    v = np.array([[p.X, p.Y, p.Z] for p in surface.Vertices])
    assert np.allclose(v, shell.points)


def test_example_scenes_parse_from_another_folder(monkeypatch, tmp_path):
    # a mesh file is found relative to the scene, wherever the command runs
    monkeypatch.chdir(tmp_path)
    scene = load_scene(SCENES / "lattice_dome.toml")
    assert len(scene["mesh"].points) == 37
    with pytest.raises(SceneError, match="geometry.file"):
        parse_scene({"geometry": {"type": "file", "file": "lattice_dome.obj"},
                     "members": [{"kind": "bar", "EA": 1.0}]})


def test_l_shaped_timber_gridshell_is_erected_and_buckles_above_its_weight(run):
    code, out, summary = run("l_shape_gridshell")
    b = summary["buckling"]
    # the unstructured quads' straight edge chains became laths, bent from straight into the form
    assert b["n_rods"] > 20 and b["rest_shape"] == "straight" and b["section"]["section"] == "rectangle"
    assert b["critical_kind"] in ("limit", "bifurcation") and b["critical_load_factor"] > 1.0
    assert not summary.get("warnings")
    events = json.loads((out / "buckling_path_events.json").read_text())["events"]
    assert events[0]["located"] and events[0]["load"] == pytest.approx(b["critical_load_factor"], rel=1e-12)
    # the critical point's state and mode, and the laths' internal forces, read back
    critical = meshio.read(out / "buckling_path_critical_1.vtu")
    mode = critical.point_data["mode"]
    assert mode.shape == (len(critical.points), 3) and np.linalg.norm(mode) > 0
    lines = {k: v["line"] for k, v in critical.cell_data_dict.items() if "line" in v}
    for field in ("axial_force", "bending_moment_1", "bending_moment_2", "torque", "max_stress"):
        assert field in lines and np.all(np.isfinite(lines[field])), field
    assert np.abs(lines["bending_moment_1"]).max() > 0  # bent into the form: never zero-filled
    table = read_csv(out / "buckling_path.csv")
    assert table["lam"].max() <= b["critical_load_factor"] * (1 + 1e-9)
