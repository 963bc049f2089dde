"""Sliding supports on tilted planes and lines: the reaction normal to the plane or line, in every analysis."""

import json

import numpy as np
import pytest

from shellform import Structure, build_system, solve_static
from shellform.effects.sliding import SlidingSupports
from shellform.errors import SceneError
from shellform.scene import parse_scene
from shellform.solvers.relaxation import relax

RAIL = np.array([np.cos(np.radians(30.0)), 0.0, np.sin(np.radians(30.0))])


def test_the_spring_energy_its_gradient_and_hessian():
    rng = np.random.default_rng(3)
    n = rng.normal(size=3)
    P = np.outer(n, n) / (n @ n)
    e = SlidingSupports(9, [0, 2], np.stack([P, np.eye(3) - P]), rng.normal(size=(2, 3)), [3.0, 5.0])
    q = rng.normal(size=9)
    g = e.gradient(q)
    rows, cols, vals = e.hessian(q)
    H = np.zeros((9, 9))
    np.add.at(H, (rows, cols), vals)
    h = 1e-6
    for k in range(9):
        dq = np.zeros(9)
        dq[k] = h
        assert (e.energy(q + dq) - e.energy(q - dq)) / (2 * h) == pytest.approx(g[k], abs=1e-8)
        np.testing.assert_allclose((e.gradient(q + dq) - e.gradient(q - dq)) / (2 * h), H[:, k], atol=1e-8)


def test_a_bar_end_on_a_tilted_plane_is_held_normal_to_it():
    """A horizontal bar whose free end slides on a plane tilted 30 degrees, loaded by 10 N downwards:
    the plane pushes along its normal with 10 / cos 30 N, the bar pulls with 10 tan 30 N."""
    s = Structure([[0, 0, 0], [1.0, 0, 0]])
    s.add_bars([[0, 1]], EA=1e6)
    s.fix([0])
    s.fix([1], "y")
    normal = np.array([np.sin(np.radians(30.0)), 0.0, np.cos(np.radians(30.0))])
    s.slide([1], "plane", normal)
    s.add_load([1], [0.0, 0.0, -10.0])
    system = build_system(s)
    res = solve_static(system, lam=1.0)
    assert res.success, res.message
    R = system.reactions(res.q)[:6].reshape(2, 3)
    # equilibrium of the end in the deformed geometry: -T b + R n + (0, 0, -10) = 0
    b = res.q[3:6] - res.q[:3]
    b /= np.linalg.norm(b)
    T, Rn = np.linalg.solve(np.column_stack([-b, normal])[[0, 2]], [0.0, 10.0])
    np.testing.assert_allclose(R[1], Rn * normal, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(R[0], -T * b, rtol=1e-9, atol=1e-9)
    assert Rn == pytest.approx(10.0 / np.cos(np.radians(30.0)), rel=1e-5)
    # off its plane by the reaction over the spring (1e2 times the bar's EA / L)
    assert abs((res.q[3:6] - [1.0, 0, 0]) @ normal) == pytest.approx(11.547 / 1e8, rel=1e-3)


def test_a_chain_hangs_from_a_ring_on_an_inclined_rail():
    """The ring slides down the rail until the rail pushes on it only across itself; the supports carry the
    chain's weight."""
    n = 8
    x = np.column_stack([np.linspace(0, 2.0, n + 1), np.zeros(n + 1), np.zeros(n + 1)])
    s = Structure(x)
    s.add_ropes(np.column_stack([np.arange(n), np.arange(1, n + 1)]), EA=1e5, slack=0.2, mass_per_length=1.0)
    s.fix([0])
    s.fix(np.arange(1, n), "y")
    s.slide([n], "line", RAIL)
    s.set_gravity((0.0, 0.0, -9.81))
    system = build_system(s)
    res = relax(system, scheme="implicit", rtol=1e-10)
    assert res.success, res.message
    X = res.q[: 3 * (n + 1)].reshape(-1, 3)
    R = system.reactions(res.q)[: 3 * (n + 1)].reshape(-1, 3)
    assert abs(R[n] @ RAIL) < 1e-8 * np.linalg.norm(R[n])
    np.testing.assert_allclose(R.sum(axis=0), [0.0, 0.0, 9.81 * 1.2 * 2.0], atol=1e-8)
    assert np.linalg.norm(np.cross(X[n] - x[n], RAIL)) < 1e-6  # on its rail, to R / K
    assert X[n, 2] < -1.0  # it slid down the rail


def _cable_net(tmp_path, replace):
    from pathlib import Path

    text = (Path(__file__).resolve().parents[1] / "scenes" / "cable_net.toml").read_text()
    for old, new in replace.items():
        assert old in text
        text = text.replace(old, new)
    (tmp_path / "net.toml").write_text(text)
    return tmp_path / "net.toml"


WEST = 'curve = [[0.0, 0.0, 0.0], [0.0, 12.0, 0.0]]\ndofs = "xz"'
EAST = 'curve = [[12.0, 0.0, 0.0], [12.0, 12.0, 0.0]]\ndofs = "xz"'


def test_a_net_hung_from_a_rail_and_a_tilted_wall_is_found_and_inverted(tmp_path):
    from shellform.cli import main

    scene = _cable_net(tmp_path, {
        WEST: 'curve = [[0.0, 0.0, 0.0], [0.0, 12.0, 0.0]]\nslide = "line"\nslide_direction = [0.0, 1.0, 0.0]',
        EAST: 'curve = [[12.0, 0.0, 0.0], [12.0, 12.0, 0.0]]\nslide = "plane"\nslide_direction = [1.0, 0.0, -0.3]'})
    assert main(["run", str(scene), "--out", str(tmp_path / "out"), "--quiet"]) == 0
    s = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert s["converged"] and s["residual_over_weight"] < 1e-8
    assert s["reaction_sum"][2] == pytest.approx(s["total_weight"], rel=1e-9)
    # the shell, mirrored, pushes on the mirrored wall and rail as the net pulled on them
    assert s["inverted"]["equilibrium_residual_over_weight"] < 1e-8


@pytest.mark.parametrize("entry, key, message", [
    ('nodes = [0]\nslide = "plane"', "slide_direction", "needs the plane's normal"),
    ('nodes = [0]\nslide = "line"\nslide_direction = [0.0, 1.0, 0.0]\ndofs = "z"', "dofs", "not both"),
    ('nodes = [0]\nslide_direction = [0.0, 1.0, 0.0]', "slide_direction", "applies with slide"),
    ('nodes = [0]\nslide = "plane"\nslide_direction = [0.0, 0.0, 0.0]', "slide_direction", "needs a length"),
])
def test_a_sliding_support_names_its_plane_or_line(entry, key, message):
    import tomllib

    text = ('[nodes]\ncoordinates = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]\n[[members]]\nkind = "bar"\n'
            'connectivity = [[0, 1]]\nEA = 1.0\n[[supports]]\nnodes = [1]\n[[supports]]\n' + entry + "\n")
    with pytest.raises(SceneError, match=message) as err:
        parse_scene(tomllib.loads(text))
    assert err.value.key.endswith(key)
