"""MRA form-finding workflow: 9 x 4 net, hypostatic check, inversion, lengths, starts, cases."""

import json

import meshio
import numpy as np
import pytest

from shellform import MechanismError, ModelError, SceneError
from shellform.analyses.form_finding import run_mra_case
from shellform.geometry import dish, disk_grid, rectangle_grid
from shellform.mra import (
    HypostaticWarning,
    OverstretchWarning,
    control_lengths,
    fit_height_field,
    form_find,
    hanging_net,
    hypostatic_check,
    invert,
    kmeans_1d,
    length_statistics,
    surface_start,
)

SIX_POINTS = {"positions": [[0, 0], [-1, 0], [0, -1], [-1, -1], [0, 2], [-1, 2]]}


@pytest.fixture(scope="module")
def net_9x4():
    return hanging_net(rectangle_grid(9.0, 4.0, 9, 4), SIX_POINTS, slack=0.05)


@pytest.fixture(scope="module")
def hung_9x4(net_9x4):
    # tolerances well below the equilibrium the tests check (residual < 1e-8 of the weight)
    return form_find(net_9x4, rtol=1e-10)


def test_9x4_net_hangs_with_every_rope_taut(hung_9x4):
    res = hung_9x4
    assert res.converged, res.relaxation.message
    assert res.slack.sum() == 0 and np.all(res.tension > 0)
    assert res.residual_over_weight < 1e-8
    # the suspension points carry the whole weight, and the horizontal pulls cancel
    W = res.net.total_weight()
    assert res.reactions[:, 2].sum() == pytest.approx(W, rel=1e-8)
    assert np.allclose(res.reactions[:, :2].sum(axis=0), 0.0, atol=1e-8 * W)
    # the shape is symmetric about both mid-lines of the planform
    x = res.positions
    mirrored = np.column_stack([9.0 - x[:, 0], x[:, 1], x[:, 2]])
    d = np.linalg.norm(mirrored[:, None, :] - x[None, :, :], axis=2).min(axis=1)
    assert d.max() < 1e-7
    assert res.rise > 0


def test_hypostatic_counts_of_the_9x4_net(hung_9x4):
    h = hung_9x4.hypostatic
    # 50 nodes: 6 suspension points, 20 other rim nodes, 24 interior nodes
    assert (h.n_t, h.n_A, h.n_B, h.n_C1, h.n_C2, h.n_interior) == (50, 6, 0, 20, 0, 24)
    assert h.dof == 300 and h.doc == 9 * 6 + 6 * 20 + 50
    assert h.hypostatic and h.warning is None


def test_not_hypostatic_net_warns_and_mechanism_is_refused():
    grid = rectangle_grid(2.0, 2.0, 2, 2)
    net = hanging_net(grid, {"groups": ["boundary"]}, slack=0.05)  # one free node of nine
    assert not hypostatic_check(net.structure).hypostatic
    with pytest.warns(HypostaticWarning, match="not hypostatic"):
        res = form_find(net)
    assert res.converged and res.warnings
    # supports that hold only z let the net slide away sideways: the solver cannot handle that
    sliding = hanging_net(rectangle_grid(3.0, 3.0, 3, 3), {"groups": ["corners"], "dofs": "z"}, slack=0.05)
    with pytest.raises(MechanismError, match="translate freely"):
        form_find(sliding)


def test_explicit_scheme_finds_the_same_shape():
    net = hanging_net(rectangle_grid(9.0, 4.0, 9, 4), SIX_POINTS, slack=0.05, EA=1e4)
    fast = form_find(net, scheme="implicit")
    paper = form_find(net, scheme="rk4")
    assert paper.converged and fast.converged
    assert np.max(np.abs(paper.positions - fast.positions)) < 1e-6
    assert np.allclose(paper.tension, fast.tension, rtol=1e-5)
    assert paper.relaxation.iterations > 50 * fast.relaxation.iterations


def test_inverted_shell_is_in_compression_and_in_equilibrium(hung_9x4):
    res = hung_9x4
    dome = invert(res)
    x, xi = res.positions, dome.positions
    assert np.allclose(xi[:, :2], x[:, :2])
    assert np.allclose(xi[:, 2], -x[:, 2])  # supports at z = 0: the mirror plane
    assert np.all(dome.force < 0)
    assert np.allclose(dome.force, -res.tension, rtol=1e-9)
    # the bar structure of the dome, assembled by the core, is in equilibrium under the same weight
    assert dome.equilibrium_residual < 1e-8
    assert dome.reactions[:, 2].sum() == pytest.approx(res.net.total_weight(), rel=1e-8)
    assert dome.summary()["rise"] == pytest.approx(res.rise)


def test_length_statistics_and_classes():
    lengths = np.array([1.0, 1.004, 0.998, 1.5, 1.502, 2.0])
    st = length_statistics(lengths, tol=0.01, target=1.0)
    assert st["n_within_target"] == 3
    assert st["n_classes"] == 3 and st["n_in_largest_class"] == 3
    assert st["min"] == 0.998 and st["max"] == 2.0
    c, lab = kmeans_1d(lengths, 3)
    assert np.allclose(c, [np.mean(lengths[:3]), 1.501, 2.0])
    st2 = length_statistics(lengths, tol=0.001, centres=c)
    assert st2["n_conforming"] == 4  # 1.004 and 0.998 are more than 0.1 % away from 1.000667


def test_length_control_increases_conforming_ropes():
    net = hanging_net(disk_grid(4.0, 8), {"groups": ["boundary"]}, slack=0.05)
    res = form_find(net)
    lc = control_lengths(res, n_classes=3, tol=0.01, rounds=3)
    assert lc.result.converged
    assert lc.n_conforming[0] < max(lc.n_conforming[1:])
    stats = lc.summary()["statistics"]
    assert stats["n_conforming"] == max(lc.n_conforming[1:])
    assert stats["n_classes"] == 3
    # the strains of the kept round, which say whether its lengths are the cut lengths too
    kept = lc.result.length / lc.result.net.rest_length - 1
    assert lc.summary()["strain_max"] == pytest.approx(kept.max())
    assert lc.summary()["n_overstretched_ropes"] == int(np.sum(kept > 0.01))


def test_surface_start_reaches_the_same_equilibrium(net_9x4, hung_9x4):
    x = hung_9x4.positions
    fitted = fit_height_field(x, (0.0, 9.0), (0.0, 4.0), n_ctrl=6)
    assert np.max(np.abs(fitted.z(x[:, 0], x[:, 1]) - x[:, 2])) < 0.1 * hung_9x4.rise
    q0 = surface_start(net_9x4, fitted)
    assert np.allclose(q0.reshape(-1, 3)[net_9x4.supports], net_9x4.structure.nodes[net_9x4.supports])
    res = form_find(net_9x4, q0)
    assert res.converged
    assert np.max(np.abs(res.positions - x)) < 1e-7
    q1 = surface_start(net_9x4, dish((0, 9), (0, 4), 1.0))
    assert q1.reshape(-1, 3)[:, 2].min() < -0.5


def test_run_mra_case_writes_meshes_and_summary(tmp_path):
    params = {
        "name": "small",
        "geometry": {"type": "rectangle", "length_x": 9.0, "length_y": 4.0, "n_i": 9, "n_j": 4},
        "supports": SIX_POINTS,
        "ropes": {"slack": 0.05},
        "start": {"type": "nurbs", "depth": 1.5, "compare_flat": True},
        "lengths": {"target": 1.05, "tolerance": 0.001},
    }
    lines = []
    s = run_mra_case(params, tmp_path, progress=lines.append)
    for key in ("converged", "iterations", "max_velocity", "max_acceleration", "n_slack_ropes", "rise",
                "rope_lengths", "wall_time_s"):
        assert key in s
    assert s["converged"] and s["n_slack_ropes"] == 0
    assert s["rope_lengths"]["n_within_target"] == 85
    assert s["start"]["flat"]["max_position_difference"] < 1e-7
    assert json.loads((tmp_path / "summary.json").read_text())["n_ropes"] == 85
    hang = meshio.read(tmp_path / "hanging.vtu")
    dome = meshio.read(tmp_path / "inverted.vtu")
    assert len(hang.cells_dict["line"]) == 85 and len(hang.cells_dict["quad"]) == 36
    assert np.allclose(dome.points[:, 2], -hang.points[:, 2])
    assert np.all(dome.cell_data_dict["axial_force"]["line"] < 0)
    rope = hang.cell_data_dict
    assert np.allclose(rope["strain"]["line"], rope["length"]["line"] / rope["rest_length"]["line"] - 1)
    assert rope["strain"]["line"].max() == pytest.approx(s["strain_max"])
    assert any("iteration" in line for line in lines)


def test_case_input_errors_name_the_key(tmp_path):
    good = {"geometry": {"type": "disk", "radius": 2.0, "n": 4}, "supports": {"groups": ["boundary"]}}
    with pytest.raises(SceneError, match="geometry.type"):
        run_mra_case({**good, "geometry": {"type": "torus"}}, tmp_path)
    with pytest.raises(SceneError, match="geometry.radius"):
        run_mra_case({**good, "geometry": {"type": "disk", "n": 4}}, tmp_path)
    with pytest.raises(SceneError, match="solver.schem"):
        run_mra_case({**good, "solver": {"schem": "rk4"}}, tmp_path)
    with pytest.raises(SceneError, match="start.depth"):
        run_mra_case({**good, "start": {"type": "nurbs"}}, tmp_path)


def test_case_on_a_bspline_surface_grid(tmp_path):
    g = np.linspace(0.0, 6.0, 4)
    X, Y = np.meshgrid(g, g, indexing="ij")
    Z = 1.5 * np.sin(np.pi * X / 6.0) * np.sin(np.pi * Y / 6.0)  # a bump: the grid's reference surface
    params = {
        "geometry": {"type": "bspline", "control_points": np.stack([X, Y, Z], axis=-1).tolist(), "n_i": 6, "n_j": 6},
        "supports": {"groups": ["corners"]},
        "ropes": {"slack": 0.02},
        "output": {"meshes": False},
    }
    s = run_mra_case(params, tmp_path)
    assert s["converged"] and s["n_nodes"] == 49 and s["n_ropes"] == 84
    assert s["hypostatic"]["n_A"] == 4
    # the ropes remember the curved surface: rest lengths differ from the flat spacing of 1 m
    assert s["rope_lengths"]["max"] > 1.05


@pytest.mark.parametrize("start, expected", [("auto", "force_density"), ("reference", "reference")])
def test_case_solver_start_and_linear_solver_keys(tmp_path, start, expected):
    params = {
        "geometry": {"type": "rectangle", "length_x": 9.0, "length_y": 4.0, "n_i": 9, "n_j": 4},
        "supports": SIX_POINTS,
        "ropes": {"slack": 0.05},
        "solver": {"start": start, "linear_solver": "ldl"},
        "output": {"meshes": False},
    }
    s = run_mra_case(params, tmp_path)
    assert s["converged"] and s["n_slack_ropes"] == 0
    assert s["start"]["relaxation_start"] == expected
    with pytest.raises(ModelError, match="unknown start 'sideways'"):
        run_mra_case({**params, "solver": {"start": "sideways"}}, tmp_path)


def test_ropes_between_suspension_points_are_left_out(tmp_path):
    # an arched frame (2 m rise over 8 m) would stretch the ropes along it by 9 %: they belong
    # to the support, so they are left out and only their weight remains, hung on the frame
    params = {
        "geometry": {"type": "rectangle", "length_x": 8.0, "length_y": 4.0, "n_i": 8, "n_j": 4},
        "supports": {"frames": [{"from": [0, 0], "to": [8, 0], "rise": 2.0}, {"from": [0, 4], "to": [8, 4]}]},
        "ropes": {"slack": 0.05},
        "output": {"meshes": False},
    }
    with pytest.warns(OverstretchWarning):
        s = run_mra_case(params, tmp_path)
    assert s["converged"]
    assert s["n_ropes_between_supports"] == 16  # eight along each frame
    assert s["n_ropes"] == 8 * 5 + 9 * 4 - 16
    # the supports carry the whole weight, the left-out ropes' share included
    assert s["reaction_sum"] == pytest.approx([0.0, 0.0, s["total_weight"]], abs=1e-6 * s["total_weight"])


def test_reactions_are_the_net_ropes_pull_and_the_supports_own_weight():
    net = _net_under_an_arch(2.0)
    with pytest.warns(OverstretchWarning):
        res = form_find(net)
    x, (a, b) = res.positions, net.rope_edges.T
    pull = res.tension[:, None] * (x[b] - x[a]) / res.length[:, None]  # on end a, towards b
    force = np.zeros_like(x)
    np.add.at(force, a, pull)
    np.add.at(force, b, -pull)
    s = net.structure
    force += s.nodal_mass()[:, None] * s.gravity
    # a support holds its node against the ropes' pull and the node's weight, nothing more
    scale = float(np.abs(res.reactions).max())
    assert res.reactions == pytest.approx(-force[net.supports], abs=1e-9 * scale)
    assert scale < 2 * res.summary()["tension_max"]


def test_ropes_between_sliding_supports_stay_in_the_net():
    grid = rectangle_grid(8.0, 4.0, 8, 4)
    held = hanging_net(grid, {"groups": ["boundary"]}, slack=0.05)
    sliding = hanging_net(grid, {"groups": ["boundary"], "dofs": "z"}, slack=0.05)
    # the 24 rim edges of the 8 x 4 grid join two suspension points
    assert len(held.info["held_ropes"]) == 24 and len(held.rope_edges) == len(grid.edges) - 24
    assert len(sliding.rope_edges) == len(grid.edges) and len(sliding.info["held_ropes"]) == 0
    # the left-out ropes' mass stays in the net's weight, and is counted once in the default EA
    assert held.total_weight() == pytest.approx(sliding.total_weight())
    assert held.EA == pytest.approx(1e4 * held.total_weight())
    assert sliding.EA == pytest.approx(1e4 * sliding.total_weight())
    with pytest.raises(ModelError, match="every rope joins two suspension points"):
        hanging_net(grid, {"groups": ["boundary"], "positions": [[i, j] for i in range(9) for j in range(5)]})


def _net_under_an_arch(rise):
    grid = rectangle_grid(8.0, 4.0, 8, 4)
    frames = {"frames": [{"from": [0, 0], "to": [8, 0], "rise": rise}, {"from": [0, 4], "to": [8, 4]}]}
    return hanging_net(grid, frames, slack=0.05)


def test_ropes_the_supports_overstretch_are_named():
    # a 2 m arch over a 4 m wide net with 5 % slack: at mid-span the cross ropes must reach
    # from (4, 0, 2) to (4, 4, 0), 4.47 m, with 4.2 m of rope: 6.5 % of stretch
    with pytest.warns(OverstretchWarning, match=r"stretched beyond 1 % at rest, the worst by 6\.[0-9]+ %"):
        res = form_find(_net_under_an_arch(2.0))
    assert res.converged
    s = res.summary()
    assert 0.06 < s["strain_max"] < 0.07 and s["n_overstretched_ropes"] > 0
    worst = np.argmax(res.strain)
    # the worst rope crosses the net at mid-span, starting on the arch
    a, b = res.net.rope_edges[worst]
    assert res.net.structure.nodes[[a, b], 0] == pytest.approx([4.0, 4.0])
    assert f"nodes {a}-{b}" in s["warnings"][-1]
    # a lower arch leaves the ropes at the strain their weight gives (EA = 1e4 x weight)
    low = form_find(_net_under_an_arch(0.5))
    assert low.summary()["strain_max"] < 1e-3 and not low.warnings
    # the limit is the caller's
    assert form_find(_net_under_an_arch(2.0), strain_limit=0.1).summary()["n_overstretched_ropes"] == 0
    with pytest.raises(ModelError, match="strain_limit must be a positive number"):
        form_find(_net_under_an_arch(0.5), strain_limit=float("nan"))


def test_scene_reference_states_the_case_defaults_of_the_ropes():
    # the schema (what `shellform schema` and docs/scenes.md print) cannot import the solver
    # modules, so its defaults are written out: they must be the ones a case uses
    from shellform.mra.case import DEFAULTS
    from shellform.scene.format import SCENE

    ropes = SCENE.keys["ropes"].keys
    assert {k: ropes[k].default for k in DEFAULTS["ropes"]} == DEFAULTS["ropes"]


def test_length_control_leaves_the_ropes_the_supports_overstretch_alone():
    # a 2 m arch over a 4 m wide net: the ropes next to it are 6.5 % too short for the gap;
    # giving them a shorter rest length for a class would only stretch them further
    grid = rectangle_grid(8.0, 4.0, 12, 6)
    frames = {"frames": [{"from": [0, 0], "to": [-1, 0], "rise": 2.0}, {"from": [0, -1], "to": [-1, -1]}]}
    net = hanging_net(grid, frames, slack=0.05)
    with pytest.warns(OverstretchWarning):
        res = form_find(net)
        lc = control_lengths(res, n_classes=3, tol=0.01, rounds=3)
    assert lc.result is not res and lc.result.converged  # a later round was kept
    over = res.overstretched
    assert over.sum() == 42
    assert lc.result.net.rest_length[over] == pytest.approx(net.rest_length[over], rel=1e-14)
    assert lc.result.net.rest_length[~over] != pytest.approx(net.rest_length[~over])
    # the arch stretches them as much as before control, not more
    assert lc.result.strain.max() <= res.strain.max() * (1 + 1e-3)
    assert lc.n_conforming[-1] > lc.n_conforming[0]


@pytest.mark.parametrize("start", ["coarse_nurbs", "coarse_force_density"])
def test_coarse_starts_reach_the_flat_start_shape(tmp_path, start):
    params = {
        "geometry": {"type": "rectangle", "length_x": 8.0, "length_y": 4.0, "n_i": 16, "n_j": 8},
        "supports": {"groups": ["corners"], "frames": [{"from": [0, 0], "to": [0, 8]}, {"from": [16, 0], "to": [16, 8]}]},
        "ropes": {"slack": 0.05},
        "start": {"type": start, "coarsening": 4, "compare_flat": True},
        "output": {"meshes": False},
    }
    lines = []
    s = run_mra_case(params, tmp_path, progress=lines.append)
    assert s["converged"] and s["start"]["type"] == start and s["start"]["coarse_converged"]
    assert s["start"]["coarse_nodes"] == 5 * 3
    # the coarse net's steps are shown, labelled as such
    coarse = [line for line in lines if line.startswith("  coarse net of 15 nodes:")]
    assert any("iteration 1:" in line for line in coarse)
    assert coarse[-1].startswith(f"  coarse net of 15 nodes: at rest after {s['start']['coarse_iterations']} steps, ")
    flat = s["start"]["flat"]
    assert flat["converged"] and flat["max_position_difference"] < 1e-6


@pytest.mark.parametrize("key", ["front_sweeps", "factor_correction", "slack_settling", "step_repair"])
def test_a_scene_can_turn_each_solver_refinement_off(key):
    from shellform.mra.case import _merge, _solver_options

    assert getattr(_solver_options(_merge({}), None)["options"].refinements, key) is True
    assert getattr(_solver_options(_merge({"solver": {key: False}}), None)["options"].refinements, key) is False
