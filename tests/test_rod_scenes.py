"""Rods in scenes: layouts from lines and mesh edge chains, sections by shape, joints, and the example gridshell."""

import json
import tomllib
from pathlib import Path

import meshio
import numpy as np
import pytest
from helpers import all_finite

from shellform.errors import SceneError
from shellform.io.table import read_csv
from shellform.rods.mesh_lines import edge_chains
from shellform.scene import build_model, load_scene, parse_scene
from shellform.solvers import solve_static

ROOT = Path(__file__).resolve().parents[1]
SCENES = ROOT / "scenes"
GRIDSHELL = SCENES / "rod_gridshell.toml"


def grid_quads(ni, nj):
    idx = np.arange(ni * nj).reshape(ni, nj)
    return np.stack([idx[:-1, :-1], idx[1:, :-1], idx[1:, 1:], idx[:-1, 1:]], axis=2).reshape(-1, 4)


def test_edge_chains_of_a_quad_grid_and_an_l_shape():
    chains = edge_chains(12, grid_quads(4, 3))
    assert sorted(len(c) for c, _ in chains) == [3, 3, 3, 3, 4, 4, 4]
    assert not any(closed for _, closed in chains)
    # cut out one corner quad: lines stop at the re-entrant corner and at the new corners
    quads = [q for q in grid_quads(4, 3).tolist() if q != [7, 10, 11, 8]]
    got = {tuple(c) for c, _ in edge_chains(12, quads)}
    assert (2, 5, 8) in got and (9, 10) in got and (6, 7, 8) in got
    # every edge of the mesh lies on exactly one chain
    edges = {tuple(sorted((q[k], q[(k + 1) % 4]))) for q in quads for k in range(4)}
    on_chains = [tuple(sorted(e)) for c, _ in edge_chains(12, quads) for e in zip(c[:-1], c[1:])]
    assert sorted(on_chains) == sorted(edges)


def test_a_ring_of_quads_gives_closed_rods():
    n = 8  # a band of 8 quads around a cylinder: two rings and 8 straight rods
    quads = [[k, (k + 1) % n, n + (k + 1) % n, n + k] for k in range(n)]
    chains = edge_chains(2 * n, quads)
    assert sorted((len(c), closed) for c, closed in chains) == [(2, False)] * n + [(n, True)] * 2


def portal(**rods):
    """A portal frame of one rectangular rod through [nodes], pinned at its feet."""
    return {
        "nodes": {"coordinates": [[0, 0, 0], [0, 0, 1], [0, 0, 2], [1, 0, 2], [2, 0, 2], [2, 0, 1], [2, 0, 0]]},
        "rods": {"E": 1.0e10, "G": 6.0e8, "section": "rectangle", "depth": 0.1, "width": 0.05,
                 "lines": [{"nodes": [0, 1, 2, 3, 4, 5, 6]}], **rods},
        "supports": [{"nodes": [0, 6]}],
        "loads": [{"nodes": [3], "force": [0.0, 0.0, -1000.0]}],
        "analysis": {"type": "static"},
    }


def test_portal_frame_from_lines_carries_its_load_with_stress_where_the_section_is_known(tmp_path):
    scene = parse_scene(portal())
    model = build_model(scene)
    res = solve_static(model.system, lam=1.0)
    assert res.success, res.message
    assert [e.name for e in model.system.effects] == ["rod_stretch", "rod_bend", "rod_twist", "loads"]
    R = res.reactions[: 3 * 7].reshape(-1, 3)
    assert R[:, 2].sum() == pytest.approx(1000.0, rel=1e-9)
    bend = model.system.effects[1]
    fields = bend.line_results(res.q).fields
    assert np.all(np.isfinite(fields["max_stress"])) and np.all(fields["max_stress"] > 0)


def test_rod_scene_keys_are_checked():
    with pytest.raises(SceneError, match="rods.depth"):
        build_model(parse_scene({**portal(), "rods": {k: v for k, v in portal()["rods"].items() if k != "depth"}}))
    with pytest.raises(SceneError, match="rods.thickness"):
        build_model(parse_scene(portal(thickness=0.01)))
    with pytest.raises(SceneError, match="rods.lines\\[0\\].nodes"):
        build_model(parse_scene(portal(lines=[{"nodes": [0, 1, 99]}])))
    with pytest.raises(SceneError, match="rods.layout"):
        build_model(parse_scene(portal(lines=[], layout="mesh_lines")))
    with pytest.raises(SceneError, match="rods.orientation"):
        build_model(parse_scene(portal(orientation="surface")))
    with pytest.raises(SceneError, match="rods.E"):
        build_model(parse_scene({**portal(), "rods": {k: v for k, v in portal()["rods"].items() if k != "E"}}))


def gridshell(**changes):
    data = tomllib.loads(GRIDSHELL.read_text())
    data["rods"].update(changes)
    data["analysis"] = {"type": "static"}
    return parse_scene(data, base_dir=SCENES)


def test_shared_and_penalty_joints_give_the_same_gridshell():
    """Penalty joints tie copies of the crossing nodes: the same equilibrium to the joint's compliance."""
    crowns, masses = [], []
    for joints in ("shared", "penalty"):
        model = build_model(gridshell(joints=joints))
        res = solve_static(model.system, lam=1.0)
        assert res.success, res.message
        crowns.append(res.q[3 * 40 + 2] - model.structure.nodes[40, 2])
        masses.append(model.structure.nodal_mass().sum())  # the cladding is on the scene's nodes, not on copies
    assert masses[1] == pytest.approx(masses[0], rel=1e-12)
    assert crowns[0] < 0
    assert crowns[1] == pytest.approx(crowns[0], rel=1e-3)


def test_example_gridshell_scene_runs_static_and_continuation_and_reads_back(tmp_path):
    from shellform.cli import main

    scene = load_scene(GRIDSHELL)
    assert scene["analysis"]["type"] == "continuation"
    assert main(["run", str(GRIDSHELL), "--out", str(tmp_path / "path"), "--quiet"]) == 0
    summary = json.loads((tmp_path / "path" / "summary.json").read_text())
    assert summary["converged"] is True and all_finite(summary)
    assert summary["units"]["fields"]["max_stress"] == "Pa"
    table = read_csv(tmp_path / "path" / "path.csv")
    assert table["lam"][0] == 0.0 and np.all(np.isfinite(table["lam"]))
    events = json.loads((tmp_path / "path" / "path_events.json").read_text())["events"]
    assert events and 1.0 < events[0]["lam"] < 40.0  # stands under its weight, buckles within the traced range
    mesh = meshio.read(tmp_path / "path" / "path_critical_1.vtu")
    assert np.linalg.norm(mesh.point_data["mode"], axis=1).max() == pytest.approx(1.0)
    for name in ("max_stress", "bending_moment_1", "bending_moment_2", "torque", "axial_force"):
        assert np.all(np.isfinite(mesh.cell_data[name][0])), name

    (tmp_path / "static.toml").write_text(GRIDSHELL.read_text().split("[analysis]")[0].replace(
        "../meshes/rod_gridshell.obj", "rod_gridshell.obj") + '[analysis]\ntype = "static"\n')
    (tmp_path / "rod_gridshell.obj").write_bytes((ROOT / "meshes" / "rod_gridshell.obj").read_bytes())
    assert main(["run", str(tmp_path / "static.toml"), "--out", str(tmp_path / "static"), "--quiet"]) == 0
    summary = json.loads((tmp_path / "static" / "summary.json").read_text())
    assert summary["converged"] is True
    state = meshio.read(tmp_path / "static" / "state.vtu")
    stress = state.cell_data["max_stress"][0]
    # the weight at load factor 1 is carried: the support reactions balance it
    weight = 9.81 * build_model(scene).structure.nodal_mass().sum()
    assert summary["reaction_sum"][2] == pytest.approx(weight, rel=1e-8)
    assert np.all(np.isfinite(stress)) and 0 < stress.max() < 5.0e7  # below the strength of timber


def test_the_form_found_gridshell_mesh_is_what_its_generator_writes():
    import importlib.util

    spec = importlib.util.spec_from_file_location("form_found_gridshell", ROOT / "meshes" / "form_found_gridshell.py")
    generator = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(generator)
    made = generator.form_found_gridshell()
    stored = meshio.read(ROOT / "meshes" / "form_found_gridshell.obj")
    assert np.allclose(made.points, stored.points, rtol=0, atol=1e-9)
    assert np.array_equal(made.cells[0].data, stored.cells[0].data)
    # a shell rising from its supports on the plane z = 0
    assert stored.points[:, 2].min() == pytest.approx(0.0, abs=1e-12) and stored.points[:, 2].max() > 0.7


def test_tightened_joints_stiffen_the_form_found_gridshell(tmp_path):
    """The scene key puts a rotational spring at every crossing of the gridshell's laths: the 11 + 11 interior
    grid lines and the 4 edge laths meet at every one of the 13 x 13 nodes. A scissor stiffness of 1 kN m/rad
    raises the first critical load factor from 1.833 (free joints) to 3.285."""
    from shellform.cli import main
    from shellform.effects.joint_rotation import JointRotation
    from shellform.scene import build_model, parse_scene

    text = (SCENES / "form_found_gridshell.toml").read_text().replace(
        "../meshes/form_found_gridshell.obj", str(ROOT / "meshes" / "form_found_gridshell.obj")).replace(
        'rest_shape = "straight"', 'rest_shape = "straight"\njoint_rotational_stiffness = 1000.0')
    import tomllib

    model = build_model(parse_scene(tomllib.loads(text)))
    (springs,) = [e for e in model.system.effects if isinstance(e, JointRotation)]
    assert len(springs.ends) == 13 * 13 and np.allclose(springs.phi0, np.pi / 2, atol=0.2)
    (tmp_path / "g.toml").write_text(text)
    assert main(["run", str(tmp_path / "g.toml"), "--out", str(tmp_path / "out"), "--quiet"]) == 0
    events = json.loads((tmp_path / "out" / "summary.json").read_text())["events"]
    assert events[0]["lam"] == pytest.approx(3.2850, rel=1e-4)


def _form_found_scene(**replace):
    import tomllib

    from shellform.scene import parse_scene

    text = (SCENES / "form_found_gridshell.toml").read_text().replace(
        "../meshes/form_found_gridshell.obj", str(ROOT / "meshes" / "form_found_gridshell.obj"))
    for old, new in replace.items():
        text = text.replace(old, new)
    return parse_scene(tomllib.loads(text))


def test_accepting_a_state_keeps_its_equilibrium_where_twists_are_held():
    """The laths' twist is held at the pinned boundary. Accepting the erected state moves the rods' reference
    frames; measured from time-parallel frames the held twists then meant something else and the state was
    out of balance by 4.5 N of 1.5e5 N in play. From anchored frames it stays balanced to round-off."""
    from shellform.scene import build_model
    from shellform.solvers import solve_static

    model = build_model(_form_found_scene())
    system = model.system
    assert model.network.frames.anchored.sum() > 0
    erected = solve_static(system, lam=0.0)
    assert erected.success, erected.message
    before = np.linalg.norm(system.residual(erected.q, 0.0)[system.free])
    system.accept(erected.q)
    after = np.linalg.norm(system.residual(erected.q, 0.0)[system.free])
    play = np.linalg.norm(system.forces_in_play(erected.q, 0.0)[system.free])
    assert abs(after - before) < 1e-12 * play


def test_the_critical_load_does_not_depend_on_the_steps_taken():
    from shellform.analyses.continuation import path_options
    from shellform.scene import build_model
    from shellform.solvers.continuation import trace_path

    loads = []
    for increment in ("1.0", "0.05"):
        scene = _form_found_scene(**{"initial_increment = 1.0": f"initial_increment = {increment}",
                                     "max_steps = 120": "max_steps = 400"})
        model = build_model(scene)
        options, _, _ = path_options(scene, model.structure, model.system)
        res = trace_path(model.system, "load", **{**options, "stop_after_events": 1})
        loads.append(res.events[0].lam)
    # located to critical_rtol = 1e-6 each; before the frames were anchored they differed by 2e-4
    assert loads[0] == pytest.approx(loads[1], rel=3e-6)
