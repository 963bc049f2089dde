"""Form finding on any net: gmsh planforms of any shape, mesh files, edge cables and sliding supports."""

import json
from pathlib import Path

import meshio
import numpy as np
import pytest

from shellform.errors import SceneError
from shellform.geometry.meshnet import MeshNet
from shellform.mra import form_find, hanging_net
from shellform.scene import parse_scene

SCENES = Path(__file__).resolve().parents[1] / "scenes"


def _run(scene_file, out):
    from shellform.analyses import run_scene
    from shellform.scene import load_scene

    run_scene(load_scene(scene_file), out)
    summary = json.loads((out / "summary.json").read_text())
    return summary, meshio.read(out / "hanging.vtu"), meshio.read(out / "inverted.vtu")


@pytest.mark.parametrize("name", ["l_shape", "courtyard"])
def test_unstructured_planform_scene_hangs_taut_and_inverts_in_compression(name, tmp_path):
    summary, hanging, inverted = _run(SCENES / f"{name}.toml", tmp_path)
    assert summary["converged"] and summary["residual_over_weight"] < 1e-8
    assert summary["n_slack_ropes"] == 0
    assert "unstructured" in summary["switched_off"]["coarse_net_start"]
    tension = hanging.cell_data_dict["tension"]["line"]
    assert len(tension) == summary["n_ropes"] and tension.min() > 0
    assert "quad" in hanging.cells_dict
    force = inverted.cell_data_dict["axial_force"]["line"]
    assert np.all(force < 0)  # every member of the inverted shell in compression
    assert summary["inverted"]["equilibrium_residual_over_weight"] < 1e-8
    assert (tmp_path / "inverted_shell.vtu").is_file()


def test_mesh_file_net_is_form_found_like_the_planform_it_was_written_from(tmp_path):
    from shellform.geometry.planforms import polygon_planform

    boundary = [(0, 0, 0), (4, 0, 0), (4, 2, 0), (2, 2, 0), (2, 4, 0), (0, 4, 0)]
    net = polygon_planform(boundary, edge_length=0.5)
    meshio.write(tmp_path / "l.vtu", meshio.Mesh(net.nodes, [("quad", net.quads)]))
    corners = net.group("corners").tolist()
    scene = {"geometry": {"type": "file", "file": "l.vtu"}, "supports": [{"nodes": corners}],
             "ropes": {"slack": 0.05}, "analysis": {"type": "mra"}}
    from shellform.analyses import run_scene

    run_scene(parse_scene(scene, base_dir=tmp_path), tmp_path / "out")
    s = json.loads((tmp_path / "out" / "summary.json").read_text())
    direct = form_find(hanging_net(net, {"nodes": corners}, slack=0.05))
    hung = meshio.read(tmp_path / "out" / "hanging.vtu").points
    assert s["converged"] and np.max(np.abs(hung - direct.positions)) < 1e-9


def test_triangulated_net_hangs_with_its_surplus_ropes_slack():
    # a triangulated net has about three ropes per node: as many as its translations, so ropes
    # of flat rest length cannot all be taut while it sags; the relaxation still balances it
    from shellform.geometry.planforms import polygon_planform

    net = hanging_net(polygon_planform([(0, 0), (4, 0), (4, 4), (0, 4)], edge_length=0.5, elements="triangles"),
                      {"groups": ["corners"]}, slack=0.05)
    res = form_find(net)
    assert res.converged and res.residual_over_weight < 1e-8
    assert 0 < res.slack.sum() < len(res.slack)
    assert res.hypostatic.n_C1 == len(np.setdiff1d(net.grid.boundary, net.supports))


def _ring_net(x_ring):
    """Two ropes of 8 links from anchors at x = -+2, z = 0 up to a ring at height 1 on a rail along x."""
    n = 8
    left = np.linspace([-2.0, 0, 0], [x_ring, 0, 1.0], n + 1)
    right = np.linspace([x_ring, 0, 1.0], [2.0, 0, 0], n + 1)[1:]
    nodes = np.vstack([left, right])
    lines = np.column_stack([np.arange(2 * n), np.arange(1, 2 * n + 1)])
    return MeshNet(nodes, lines=lines), n


@pytest.mark.parametrize("x_ring", [0.0, 0.5])
def test_ring_sliding_on_a_horizontal_line_settles_where_statics_says(x_ring):
    # the ropes keep their rest lengths from the drawing, where the ring sits at x_ring: the rope
    # on the side the ring moved to is the shorter one. Statics: a frictionless ring passes no
    # force along the rail, so the ropes' horizontal pulls on it are equal and opposite; by
    # symmetry of the two anchors that happens where both ropes are equally long, at
    # x = x_ring if the ropes are equal (x_ring = 0) and on the longer rope's side otherwise.
    grid, n = _ring_net(x_ring)
    ends = [0, 2 * n]
    net = hanging_net(grid, [{"nodes": ends}, {"nodes": [n], "dofs": "yz"}], slack=0.0, mass_per_length=1.0)
    res = form_find(net, rtol=1e-10)
    x = res.positions
    assert res.converged and res.residual_over_weight < 1e-10
    assert x[n, 1] == 0.0 and x[n, 2] == 1.0  # on the rail
    # the ring's horizontal balance, to round-off of the rope forces
    e, t = net.rope_edges, res.tension
    pull = np.zeros(3)
    for k, (a, b) in enumerate(e):
        if n in (a, b):
            other = b if a == n else a
            d = x[other] - x[n]
            pull += t[k] * d / np.linalg.norm(d)
    # round-off of a rope force: eps (EA / L) |x| (docs/theory-mra.md), with a factor 10 for the sums
    roundoff = 10 * np.finfo(float).eps * np.max(net.EA / net.rest_length) * np.abs(x).max()
    assert abs(pull[0]) < roundoff
    assert abs(res.reactions[list(net.supports).index(n), 0]) < roundoff
    if x_ring == 0.0:
        assert abs(x[n, 0]) < 1e-12
    else:
        # the ring moves away from the anchor of the shorter rope, towards equal horizontal pulls
        assert x[n, 0] < x_ring


def test_edge_cable_scene(tmp_path):
    summary, hanging, _ = _run(SCENES / "cable_net.toml", tmp_path)
    assert summary["converged"] and summary["residual_over_weight"] < 1e-8
    family = hanging.cell_data_dict["family"]["line"]
    assert np.count_nonzero(family == 2) == 48  # two cables of 24 edges
    # the cables are taut, the net's sliding sides lie on their walls
    assert np.all(hanging.cell_data_dict["tension"]["line"][family == 2] > 0)
    x = hanging.points
    wall = np.isclose(x[:, 0] - hanging.point_data["displacement"][:, 0], 0.0)
    assert np.allclose(x[wall, 0], 0.0) and np.allclose(x[wall, 2], 0.0)


@pytest.mark.parametrize("change, key, words", [
    ({"supports": [{"positions": [[0, 0]]}]}, "supports[0].positions", "structured grid"),
    ({"ropes": {"slack": [0.1, 0.2]}}, "ropes.slack", "unstructured"),
    ({"geometry": {"type": "polygon", "boundary": [[0, 0, 0], [1, 0, 0], [0, 1, 0]], "edge_length": 0.1,
                   "curves": [{"control_points": [[0, 0, 0], [1, 0, 0]]}]}}, "geometry.curves", "applies to type"),
    ({"geometry": {"type": "surface", "file": "missing.step", "edge_length": 0.1}}, "geometry.file", "does not exist"),
    ({"cables": [{"EA": 1.0}]}, "cables[0]", "names no nodes"),
])
def test_bad_any_net_input_names_the_key(change, key, words):
    scene = {"geometry": {"type": "polygon", "boundary": [[0, 0, 0], [2, 0, 0], [2, 1, 0], [1, 1, 0], [1, 2, 0],
                                                          [0, 2, 0]], "edge_length": 0.2},
             "supports": [{"groups": ["corners"]}], "analysis": {"type": "mra"}, **change}
    with pytest.raises(SceneError) as info:
        parse_scene(scene)
    assert info.value.key == key and words in str(info.value)


def _quad_l(tmp_path, elements="quads"):
    from shellform.geometry.planforms import polygon_planform

    net = polygon_planform([(0, 0, 0), (6, 0, 0), (6, 3, 0), (3, 3, 0), (3, 6, 0), (0, 6, 0)], edge_length=0.5,
                           elements=elements)
    cells = [("quad", net.quads)] if elements == "quads" else [("triangle", net.triangles)]
    meshio.write(tmp_path / "l.vtu", meshio.Mesh(net.nodes, cells))
    return {"geometry": {"type": "file", "file": "l.vtu"}, "supports": [{"groups": ["boundary"]}],
            "ropes": {"slack": 0.05},
            "rods": {"section": "rectangle", "depth": 0.03, "width": 0.05, "E": 10e9, "G": 0.6e9, "density": 500.0},
            "analysis": {"type": "form_and_buckle", "buckling": {"load_factor_max": 200.0, "initial_increment": 2.0,
                                                                 "max_steps": 150}}}


def test_a_quad_mesh_file_is_form_found_erected_as_laths_and_buckled(tmp_path):
    from shellform.analyses import run_scene

    summary = run_scene(parse_scene(_quad_l(tmp_path), base_dir=tmp_path), tmp_path / "out")
    b = summary["buckling"]
    assert summary["converged"] and b["n_rods"] > 10 and b["critical_load_factor"] > 1.0
    assert b["critical_kind"] in ("limit", "bifurcation")


@pytest.mark.parametrize("source", ["file", "planform"])
def test_laths_are_refused_on_triangles_before_any_form_finding(tmp_path, source):
    scene = _quad_l(tmp_path, "triangles")
    key = "geometry.file"
    if source == "planform":
        scene["geometry"] = {"type": "polygon", "boundary": [[0, 0, 0], [6, 0, 0], [6, 6, 0], [0, 6, 0]],
                             "edge_length": 0.5, "elements": "triangles"}
        key = "geometry.elements"
    with pytest.raises(SceneError, match="straight edge chains of a quad net") as err:
        parse_scene(scene, base_dir=tmp_path)
    assert err.value.key == key
