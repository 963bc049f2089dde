"""Imperfections, time stepping and resumed runs against answers known beforehand."""

import copy

import meshio
import numpy as np
import pytest

from shellform.errors import SceneError
from shellform.io.table import read_csv
from shellform.analyses import run_scene
from shellform.scene import build_model, parse_scene

VON_MISES = {
    "nodes": {"coordinates": [[-1.0, 0.0, 0.0], [0.0, 0.0, 0.2], [1.0, 0.0, 0.0]]},
    "members": [{"kind": "bar", "connectivity": [[0, 1], [1, 2]], "EA": 1.0e4}],
    "supports": [{"nodes": [0, 2]}, {"nodes": [1], "dofs": "y"}],
    "loads": [{"nodes": [1], "force": [0.0, 0.0, -1.0]}],
}


def test_mode_imperfection_moves_the_apex_along_the_softest_direction():
    # node 1 is held in y; its tangent at the reference is EA/L (n1 n1^T + n2 n2^T) with
    # n = (+-cos a, sin a): 2 EA/L sin^2(a) vertically < 2 EA/L cos^2(a) horizontally
    scene = parse_scene({**copy.deepcopy(VON_MISES), "imperfection": {"type": "mode", "amplitude": -0.01}})
    model = build_model(scene)
    L = np.hypot(1.0, 0.2)
    assert model.imperfection["eigenvalue"] == pytest.approx(2 * 1.0e4 / L * (0.2 / L) ** 2, rel=1e-12)
    assert np.allclose(model.structure.nodes, [[-1.0, 0, 0], [0.0, 0, 0.19], [1.0, 0, 0]], atol=1e-14)
    # the bars are stress-free in the moved geometry
    q = model.system.q_ref
    assert np.allclose(model.system.residual(q, 0.0), 0.0, atol=1e-9)


def test_mode_imperfection_lowers_the_limit_load_of_the_truss(tmp_path):
    def limit(imperfection):
        raw = copy.deepcopy(VON_MISES)
        raw["analysis"] = {"type": "continuation", "continuation": {"parameter_max": 40.0, "max_displacement": 0.5,
                                                                     "monitor_node": 1}}
        if imperfection:
            raw["imperfection"] = imperfection
        s = run_scene(parse_scene(raw), tmp_path / str(bool(imperfection)))
        return next(e["load"] for e in s["events"] if e["kind"] == "limit")

    alpha = np.arctan(0.19)  # the lowered truss has rise 0.19 m: its analytic limit load
    expected = 2 * 1.0e4 * np.sin(np.arccos(np.cos(alpha) ** (1 / 3))) ** 3
    assert limit({"type": "mode", "amplitude": -0.01}) == pytest.approx(expected, rel=5e-3)
    assert limit({"type": "mode", "amplitude": -0.01}) < limit(None)


def test_random_imperfection_is_reproducible_and_leaves_supports_alone():
    raw = {**copy.deepcopy(VON_MISES), "imperfection": {"type": "random", "amplitude": 0.003, "seed": 7}}
    a, b = build_model(parse_scene(raw)), build_model(parse_scene(copy.deepcopy(raw)))
    assert np.array_equal(a.structure.nodes, b.structure.nodes)
    moved = a.structure.nodes - np.array(VON_MISES["nodes"]["coordinates"])
    assert np.allclose(moved[[0, 2]], 0.0) and moved[1, 1] == 0.0  # supported components stay
    assert np.linalg.norm(moved, axis=1).max() == pytest.approx(0.003, rel=1e-12)
    raw["imperfection"]["seed"] = 8
    assert not np.array_equal(build_model(parse_scene(raw)).structure.nodes, a.structure.nodes)


def test_force_imperfection_is_a_dead_load_of_the_given_size():
    raw = {**copy.deepcopy(VON_MISES), "imperfection": {"type": "forces", "amplitude": 0.5, "seed": 1}}
    model = build_model(parse_scene(raw))
    assert [e.name for e in model.system.effects] == ["axial", "loads", "imperfection"]
    f = model.system.external_force(0.0)  # the scaled apex load is off at load factor 0
    assert np.linalg.norm(f) == pytest.approx(0.5, rel=1e-12)
    assert np.allclose(f[model.structure.constrained_mask], 0.0)
    raw["effects"] = {"include": ["axial", "loads"]}
    assert "imperfection" not in [e.name for e in build_model(parse_scene(raw)).system.effects]


SPRING = {
    "title": "mass on a spring",
    "nodes": {"coordinates": [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]},
    "members": [{"kind": "bar", "connectivity": [[0, 1]], "EA": 400.0}],
    "masses": {"node_mass": 2.0},
    "supports": [{"nodes": [0]}, {"nodes": [1], "dofs": "yz"}],
    "analysis": {"type": "dynamics", "start": [[0.0, 0.0, 0.0], [1.05, 0.0, 0.0]],
                 "dynamics": {"time_step": 0.01, "duration": 0.5, "damping": 1.5, "output_every": 10,
                              "monitor_node": 1, "monitor_component": "x"}},
}


def implicit_euler_oscillator(u0, k, m, c, h, steps):
    """The discrete solution of m a + c m v + k u = 0 by implicit Euler."""
    u, v, out = u0, 0.0, [u0]
    for _ in range(steps):
        v = (m * v / h - k * u) / (m / h + k * h + c * m)
        u = u + h * v
        out.append(u)
    return np.array(out)


def test_time_stepping_of_a_spring_matches_the_implicit_euler_recurrence(tmp_path):
    summary = run_scene(parse_scene(copy.deepcopy(SPRING)), tmp_path)
    assert summary["converged"] and summary["steps"] == 50
    table = read_csv(tmp_path / "dynamics.csv")
    # an axial bar along its own axis is a linear spring k = EA / L
    expected = implicit_euler_oscillator(0.05, 400.0, 2.0, 1.5, 0.01, 50)
    assert np.allclose(table["ux1"], expected, rtol=1e-9, atol=1e-12)
    assert np.allclose(table["time"], 0.01 * np.arange(51))
    with meshio.xdmf.TimeSeriesReader(tmp_path / "dynamics.xdmf") as reader:
        reader.read_points_cells()
        assert reader.num_steps == 6  # t = 0 and every 10th of 50 steps
        for k in range(reader.num_steps):
            t, point_data, _ = reader.read_data(k)
            assert point_data["displacement"][1, 0] == pytest.approx(expected[10 * k], rel=1e-9)


def test_time_stepping_needs_mass(tmp_path):
    raw = copy.deepcopy(SPRING)
    del raw["masses"]
    with pytest.raises(SceneError, match="mass"):
        run_scene(parse_scene(raw), tmp_path)


def test_interrupted_time_stepping_resumes_where_it_stopped(tmp_path, monkeypatch):
    full = run_scene(parse_scene(copy.deepcopy(SPRING)), tmp_path / "full")
    raw = copy.deepcopy(SPRING)
    raw["analysis"]["dynamics"]["checkpoint_interval"] = 0.0
    raw["analysis"]["dynamics"]["duration"] = 0.23  # a run cut short ...
    run_scene(parse_scene(raw), tmp_path / "part")
    raw["analysis"]["dynamics"]["duration"] = 0.5  # ... continued to the end
    resumed = run_scene(parse_scene(raw), tmp_path / "part", resume=True)
    assert resumed["steps"] == full["steps"] and resumed["steps_this_run"] < full["steps"]
    a, b = read_csv(tmp_path / "full" / "dynamics.csv"), read_csv(tmp_path / "part" / "dynamics.csv")
    assert np.allclose(a["time"], b["time"], rtol=1e-12)
    assert np.allclose(a["ux1"], b["ux1"], rtol=1e-9, atol=1e-14)


NET = {
    "name": "barrel",
    "geometry": {"type": "rectangle", "length_x": 9.0, "length_y": 4.0, "n_i": 9, "n_j": 4},
    "supports": [{"positions": [[0, 0], [-1, 0], [0, -1], [-1, -1], [0, 2], [-1, 2]]}],
    "ropes": {"slack": 0.05},
    "analysis": {"type": "mra", "relaxation": {"rtol": 1e-8, "checkpoint_interval": 0.0}},
    "output": {"formats": ["vtu"]},
}


def test_interrupted_relaxation_resumes_to_the_same_form(tmp_path):
    whole = run_scene(parse_scene(copy.deepcopy(NET)), tmp_path / "whole")
    seen = []

    def interrupt(message):
        seen.append(message)
        if sum("iteration" in m for m in seen) == 8:
            raise KeyboardInterrupt  # Ctrl-C in the middle of the relaxation

    with pytest.raises(KeyboardInterrupt):
        run_scene(parse_scene(copy.deepcopy(NET)), tmp_path / "cut", progress=interrupt)
    saved = np.load(tmp_path / "cut" / "relaxation_checkpoint.npz")
    assert int(saved["iteration"]) == 7 and not bool(saved["converged"])
    resumed = run_scene(parse_scene(copy.deepcopy(NET)), tmp_path / "cut", resume=True)
    assert resumed["converged"] and resumed["start"]["type"] == "resumed"
    assert resumed["iterations"] < whole["iterations"]
    xa = meshio.read(tmp_path / "whole" / "hanging.vtu").points
    xb = meshio.read(tmp_path / "cut" / "hanging.vtu").points
    assert np.abs(xa - xb).max() < 1e-8  # m, on a 9 m net at rest to 1e-8 g
    # a checkpoint of another net is refused, not silently used
    other = copy.deepcopy(NET)
    other["ropes"]["slack"] = 0.1
    with pytest.raises(SceneError, match="different net"):
        run_scene(parse_scene(other), tmp_path / "cut", resume=True)


def test_resume_without_a_checkpoint_starts_from_the_start_shape(tmp_path):
    lines = []
    summary = run_scene(parse_scene(copy.deepcopy(NET)), tmp_path, progress=lines.append, resume=True)
    assert summary["converged"] and summary["start"]["type"] == "flat"
    assert any("no relaxation checkpoint" in m for m in lines)


NET_TOML = """
[geometry]
type = "rectangle"
length_x = 9.0
length_y = 4.0
n_i = 9
n_j = 4
[[supports]]
positions = [[0, 0], [-1, 0], [0, -1], [-1, -1], [0, 2], [-1, 2]]
[ropes]
slack = 0.05
[analysis.relaxation]
rtol = 1e-8
"""


def test_command_line_resumes_a_relaxation_stopped_by_its_step_budget(tmp_path):
    from shellform.cli import main

    whole = run_scene(parse_scene(copy.deepcopy(NET)), tmp_path / "whole")
    short, full = tmp_path / "short.toml", tmp_path / "full.toml"
    short.write_text(NET_TOML + "max_iterations = 5\n")
    full.write_text(NET_TOML)
    out = str(tmp_path / "cli")
    assert main(["run", str(short), "--out", out, "--quiet"]) == 1  # not at rest after 5 steps
    assert main(["run", str(full), "--out", out, "--quiet", "--resume"]) == 0
    xa = meshio.read(tmp_path / "whole" / "hanging.vtu").points
    xb = meshio.read(tmp_path / "cli" / "hanging.vtu").points
    assert whole["converged"] and np.abs(xa - xb).max() < 1e-8


def test_command_line_reports_an_interruption(monkeypatch, capsys, tmp_path):
    import shellform.analyses
    from shellform.cli import main

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(shellform.analyses, "run_scene", interrupted)
    assert main(["run", "von_mises", "--out", str(tmp_path), "--quiet"]) == 130
    assert "--resume" in capsys.readouterr().err


def test_a_shell_weaker_than_its_own_weight_is_flagged(tmp_path):
    """Rods of 4 mm instead of 30 mm: the found form buckles under a fraction of the weight it was
    found for, and the summary says so instead of reporting a critical load factor below 1 silently."""
    from importlib import resources

    try:
        import tomllib
    except ImportError:  # Python 3.10
        import tomli as tomllib

    raw = tomllib.loads((resources.files("shellform") / "scenes" / "default.toml").read_text())
    raw["rods"]["radius"] = 0.004
    summary = run_scene(parse_scene(raw), tmp_path)
    lam = summary["buckling"]["critical_load_factor"]
    assert lam is not None and lam < 1.0
    assert any("less than the weight it was found for" in w for w in summary["warnings"])


ROD_SWING = {
    "title": "a bent rod swinging under its weight",
    "nodes": {"coordinates": [[0.2 * i, 0.1 * np.sin(i), 0.05 * i * i] for i in range(6)]},
    "rods": {"E": 2.1e9, "radius": 0.01, "density": 1000.0, "lines": [{"nodes": [0, 1, 2, 3, 4, 5]}],
             "support_rotation": "clamped"},
    "supports": [{"nodes": [0]}],
    "gravity": {},
    "analysis": {"type": "dynamics", "dynamics": {"time_step": 0.002, "duration": 0.1, "damping": 0.0,
                                                  "output_every": 5}},
}


def test_a_rod_motion_writes_each_frame_with_its_own_rod_frames_and_resumes_with_them(tmp_path):
    """The torques of every written frame are those of the state when it was reached (a rod's twist
    angles are measured from the frames carried to it), and a run resumed from a checkpoint goes on
    with the frames of the saved state: the same series as an uninterrupted run."""
    import h5py

    summary = run_scene(parse_scene(copy.deepcopy(ROD_SWING)), tmp_path / "whole")
    assert summary["converged"]
    part = copy.deepcopy(ROD_SWING)
    part["analysis"]["dynamics"].update(checkpoint_interval=0.0, duration=0.05)
    run_scene(parse_scene(part), tmp_path / "part")
    part["analysis"]["dynamics"]["duration"] = 0.1
    run_scene(parse_scene(part), tmp_path / "part", resume=True)
    with h5py.File(tmp_path / "whole" / "dynamics.h5") as a, h5py.File(tmp_path / "part" / "dynamics.h5") as b:
        keys = sorted(a["states"], key=int)
        assert len(keys) == 11 and sorted(b["states"], key=int) == keys
        largest = max(float(np.abs(a["states"][k]["cell"]["torque"][()]).max()) for k in keys)
        assert largest > 0.1
        for k in keys:
            np.testing.assert_allclose(b["states"][k]["cell"]["torque"][()], a["states"][k]["cell"]["torque"][()],
                                       rtol=0, atol=1e-8 * largest)
            np.testing.assert_allclose(b["states"][k]["points"][()], a["states"][k]["points"][()], rtol=0, atol=1e-9)
