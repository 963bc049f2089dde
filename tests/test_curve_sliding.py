"""Supports sliding along curves: the nearest point, the spring's derivatives, and the reaction normal to
the curve in statics, form finding and the inverted shell."""

import json

import numpy as np
import pytest

from shellform import Structure, build_system, solve_static
from shellform.effects.curve_sliding import CurveSupports
from shellform.errors import ModelError, SceneError
from shellform.geometry.space_curve import SpaceCurve


def ring(radius=2.0, n=13, z=0.0):
    a = np.linspace(0.0, 2.0 * np.pi, n)
    p = np.column_stack([radius * np.cos(a), radius * np.sin(a), np.full(n, z)])
    p[-1] = p[0]
    return p


def arch(span=4.0, rise=1.0, n=9):
    """A circular arch in the plane y = 0 from (0, 0, 0) to (span, 0, 0)."""
    R = (span**2 / 4 + rise**2) / (2 * rise)
    half = np.arcsin(span / (2 * R))
    a = np.linspace(-half, half, n)
    return np.column_stack([span / 2 + R * np.sin(a), np.zeros(n), R * np.cos(a) - (R - rise)])


def test_a_closed_curve_has_no_corner_and_finds_the_nearest_point():
    c = SpaceCurve.through(ring(2.0, 25))
    assert c.closed
    a, b = c.domain
    np.testing.assert_allclose(c(a, 1), c(b, 1), atol=1e-9)  # periodic: the tangent goes round
    angles = np.linspace(0.1, 6.2, 40)
    x = np.column_stack([2.3 * np.cos(angles), 2.3 * np.sin(angles), np.full(40, 0.4)])
    t, end = c.nearest(x)
    p = c(t)
    assert not end.any()
    np.testing.assert_allclose(np.einsum("ni,ni->n", c(t, 1), x - p), 0.0, atol=1e-12)  # normal to the curve
    # the interpolated ring is the circle to its interpolation error, so the nearest point is radial
    np.testing.assert_allclose(np.arctan2(p[:, 1], p[:, 0]) % (2 * np.pi), angles, atol=2e-4)
    # an open curve's nearest point beyond its end is the end
    o = SpaceCurve.through(arch())
    t, end = o.nearest([[-1.0, 0.0, -0.5], [2.0, 0.0, 2.0]])
    assert end.tolist() == [True, False] and t[0] == o.domain[0]


def test_a_nearest_point_newton_does_not_settle_on_is_found_between_the_samples(monkeypatch):
    """Where Newton is cut off unsettled, the golden-section fallback gives the nearest point:
    normal to the curve and no farther than Newton's own answer (closed ring, open arch, a node
    beyond the arch's end)."""
    import shellform.geometry.space_curve as space_curve

    angles = np.linspace(0.1, 6.2, 23)
    x_ring = np.column_stack([2.3 * np.cos(angles), 2.3 * np.sin(angles), np.full(23, 0.4)])
    x_arch = np.array([[1.0, 0.3, 1.2], [3.1, -0.2, 0.4], [-1.0, 0.0, -0.5], [2.0, 0.0, 0.2]])
    cases = [(SpaceCurve.through(ring(2.0, 25)), x_ring), (SpaceCurve.through(arch()), x_arch)]
    answers = [c.nearest(x) for c, x in cases]
    monkeypatch.setattr(space_curve, "NEAREST_ITERATIONS", 1)
    for (c, x), (t_ref, end_ref) in zip(cases, answers):
        t, end = c.nearest(x)
        d, d_ref = np.linalg.norm(c(t) - x, axis=1), np.linalg.norm(c(t_ref) - x, axis=1)
        assert np.all(d <= d_ref + 1e-12)
        np.testing.assert_allclose(d, d_ref, rtol=1e-12)
        inside = ~end
        np.testing.assert_allclose(np.einsum("ni,ni->n", c(t, 1), x - c(t))[inside], 0.0, atol=1e-10)
        assert end.tolist() == end_ref.tolist()


def _derivative_check(effect, q, h=1e-6):
    n = len(q)
    g = effect.gradient(q)
    rows, cols, vals = effect.hessian(q)
    H = np.zeros((n, n))
    np.add.at(H, (rows, cols), vals)
    for k in range(n):
        dq = np.zeros(n)
        dq[k] = h
        assert (effect.energy(q + dq) - effect.energy(q - dq)) / (2 * h) == pytest.approx(g[k], rel=1e-7, abs=1e-9)
        np.testing.assert_allclose((effect.gradient(q + dq) - effect.gradient(q - dq)) / (2 * h), H[:, k],
                                   rtol=1e-6, atol=1e-7)


@pytest.mark.parametrize("points", [ring(2.0, 9), arch(), arch()[[0, -1]], arch(n=3)],
                         ids=["ring", "arch", "segment", "parabola"])
def test_the_spring_energy_its_gradient_and_hessian(points):
    """Nodes off the curve on both sides (a little stiffer outside an arch, softer inside), and beyond an
    open curve's end."""
    rng = np.random.default_rng(5)
    c = SpaceCurve.through(points)
    a, b = c.domain
    t = np.array([0.2, 0.45, 0.7]) * (b - a) + a
    normal = np.cross(c(t, 1), [0.0, 1.0, 0.0]) + np.cross(c(t, 1), [0.0, 0.0, 1.0])
    normal /= np.linalg.norm(normal, axis=1)[:, None]
    x = c(t) + np.array([0.05, -0.08, 0.1])[:, None] * normal
    if not c.closed:
        x = np.vstack([x, c(a) - 0.1 * c(a, 1) / np.linalg.norm(c(a, 1)) + [0.0, 0.03, 0.0]])
    shift = 1e-3 * rng.normal(size=x.shape)
    e = CurveSupports(3 * len(x), np.arange(len(x)), c, shift, 10.0 + rng.random(len(x)))
    _derivative_check(e, x.ravel())


def test_a_bar_end_on_a_ring_swings_to_where_it_is_pulled():
    """A bar from a fixed point outside a horizontal ring pulls its other end round the ring: it stops
    on the line from the ring's centre to the anchor, where the ring pushes across itself only."""
    angle = 2.0 * np.pi * 5 / 32  # at a point of the ring, about which the interpolated ring is symmetric
    anchor = np.array([5.0 * np.cos(angle), 5.0 * np.sin(angle), 1.0])
    s = Structure([anchor, [2.0, 0.0, 0.0]])
    s.add_bars([[0, 1]], EA=1e4, rest_length=2.0)  # stretched: about 3.2 m apart at the start
    s.fix([0])
    s.slide_along([1], ring(2.0, 33))
    system = build_system(s)
    res = solve_static(system, lam=1.0)
    assert res.success, res.message
    x = res.q[3:6]
    assert np.arctan2(x[1], x[0]) == pytest.approx(angle, abs=1e-12)
    R = system.reactions(res.q)[3:6]
    effect = next(e for e in system.effects if e.name == "curve_sliding")
    t, _, _ = effect.nearest(res.q)
    tangent = effect.curve(t, 1)[0]
    assert abs(R @ tangent) < 1e-9 * np.linalg.norm(R) * np.linalg.norm(tangent)
    bar = x - anchor
    T = 1e4 * (np.linalg.norm(bar) - 2.0) / 2.0
    np.testing.assert_allclose(R, T * bar / np.linalg.norm(bar), rtol=1e-9)
    # off its ring by the reaction over the spring, 1e2 times the bar's EA / L
    assert np.linalg.norm(x - effect.curve(t)[0]) == pytest.approx(np.linalg.norm(R) / (1e2 * 1e4 / 2.0), rel=1e-9)


def test_a_node_off_its_curve_and_a_bad_curve_are_named():
    s = Structure([[0.0, 0.0, 0.0], [2.0, 0.0, 0.01]])
    s.add_bars([[0, 1]], EA=1.0)
    with pytest.raises(ModelError, match=r"node 1 at \[2.0, 0.0, 0.01\] is 0.01 m from its curve"):
        s.slide_along([1], ring(2.0, 33))
    s.slide_along([1], ring(2.0, 33), tolerance=0.02)  # within a tolerance given: the curve passes through it
    with pytest.raises(ModelError, match="at least two points"):
        s.slide_along([1], [[2.0, 0.0, 0.0]])
    with pytest.raises(ModelError, match="points 1 and 2 coincide"):
        s.slide_along([1], [[0.0, 0.0, 0.0], [2.0, 0.0, 0.01], [2.0, 0.0, 0.01]])


def _points(p):
    return "[" + ", ".join(f"[{x:.15g}, {y:.15g}, {z:.15g}]" for x, y, z in p) + "]"


def _curved_wall_net(tmp_path):
    """The 12 x 12 m net of scenes/cable_net.toml with its west wall curved in plan: an arc of radius 10 m
    bulging 2 m out, whose nodes slide along the wall top."""
    from pathlib import Path

    R, half = 10.0, np.arcsin(0.6)
    a = np.linspace(np.pi + half, np.pi - half, 49)
    wall = np.column_stack([8.0 + R * np.cos(a), 6.0 + R * np.sin(a), np.zeros(49)])
    wall[0], wall[-1] = [0.0, 0.0, 0.0], [0.0, 12.0, 0.0]
    text = (Path(__file__).resolve().parents[1] / "scenes" / "cable_net.toml").read_text()
    outline = [[0.0, 0.0, 0.0], [12.0, 0.0, 0.0], [12.0, 12.0, 0.0], *wall[::-1][:-1].tolist()]
    for old, new in {
        "boundary = [[0.0, 0.0, 0.0], [12.0, 0.0, 0.0], [12.0, 12.0, 0.0], [0.0, 12.0, 0.0]]":
            "boundary = " + _points(outline),
        'groups = ["corners"]': "near = [[0.0, 0.0, 0.0], [12.0, 0.0, 0.0], [12.0, 12.0, 0.0], [0.0, 12.0, 0.0]]",
        # gmsh's nodes lie on the outline's straight pieces, up to 1.5 mm inside the smooth wall
        'curve = [[0.0, 0.0, 0.0], [0.0, 12.0, 0.0]]\ndofs = "xz"':
            f'curve = {_points(wall)}\ntolerance = 2e-3\nslide = "curve"',
    }.items():
        assert old in text
        text = text.replace(old, new)
    (tmp_path / "net.toml").write_text(text)
    return tmp_path / "net.toml", wall


def test_a_net_hung_from_a_curved_wall_it_slides_along_is_found_and_inverted(tmp_path):
    import meshio

    from shellform.cli import main

    scene, wall = _curved_wall_net(tmp_path)
    assert main(["run", str(scene), "--out", str(tmp_path / "out"), "--quiet"]) == 0
    s = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert s["converged"] and s["residual_over_weight"] < 1e-7
    assert s["reaction_sum"][2] == pytest.approx(s["total_weight"], rel=1e-9)
    assert s["inverted"]["equilibrium_residual_over_weight"] < 1e-7
    hanging = meshio.read(tmp_path / "out" / "hanging.vtu")
    x, R = hanging.points, hanging.point_data["reaction"]
    curve = SpaceCurve.through(wall)
    on_wall = np.flatnonzero((np.abs(x[:, 2]) < 1e-4) & (x[:, 0] < 0.0))  # where the wall bulges out
    assert on_wall.size > 10
    t, _ = curve.nearest(x[on_wall])
    tangent = curve(t, 1) / np.linalg.norm(curve(t, 1), axis=1)[:, None]
    # the wall pushes across itself only: each node slides along the wall moved to pass through it (by up
    # to 1.5 mm), whose tangent there turns from this one's by up to the curvature times that, 1.5e-4
    along = np.abs(np.einsum("ni,ni->n", R[on_wall], tangent))
    assert np.all(along < 2e-4 * np.linalg.norm(R[on_wall], axis=1))
    assert np.abs(R[on_wall, :2]).max() > 0.1  # and it does push sideways
    assert np.linalg.norm(x[on_wall] - curve(t), axis=1).max() < 2e-3  # on the wall (to the nodes' tolerance)
    assert np.ptp(t) > 5.0  # along a good part of it


@pytest.mark.parametrize("entry, key, message", [
    ('nodes = [1]\nslide = "curve"', "slide_curve", "needs the curve"),
    ('nodes = [1]\nslide_curve = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]', "slide_curve", "applies with slide = 'curve'"),
    ('nodes = [1]\nslide = "curve"\nslide_direction = [0.0, 1.0, 0.0]\nslide_curve = [[0.0, 0.0, 0.0], [1.0, 0.0, '
     '0.0]]', "slide_direction", "applies with slide = 'plane' or 'line'"),
    ('nodes = [1]\nslide = "curve"\nslide_curve = [[0.0, 1.0, 0.0], [1.0, 1.0, 0.0]]', "supports[1]",
     "is 1 m from its curve"),
])
def test_a_sliding_support_names_its_curve(entry, key, message):
    import tomllib

    from shellform.scene import build_structure, parse_scene

    text = ('[nodes]\ncoordinates = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]\n[[members]]\nkind = "bar"\n'
            'connectivity = [[0, 1]]\nEA = 1.0\n[[supports]]\nnodes = [0]\n[[supports]]\n' + entry + "\n")
    with pytest.raises(SceneError, match=message) as err:
        build_structure(parse_scene(tomllib.loads(text)))
    assert err.value.key.endswith(key)


def test_a_rod_portal_whose_foot_rolls_on_a_curved_track():
    """The portal frame of tests/test_rod_scenes.py with its right foot on a track that curves up on both
    sides: the beam's load spreads the frame, the foot rolls outwards and up, and the track pushes on it
    across itself only."""
    from test_rod_scenes import portal

    from shellform.scene import build_model, parse_scene
    from shellform.solvers import solve_static

    track = [[1.0, 0.0, 0.5], [2.0, 0.0, 0.0], [3.0, 0.0, 0.5]]  # a parabola, its lowest point the foot
    data = portal()
    data["supports"] = [{"nodes": [0]}, {"nodes": [6], "slide": "curve", "slide_curve": track}]
    data["loads"][0]["force"] = [0.0, 0.0, -2.0e5]
    model = build_model(parse_scene(data))
    res = solve_static(model.system, lam=1.0)
    assert res.success, res.message
    foot = res.q[18:21]
    effect = next(e for e in model.system.effects if e.name == "curve_sliding")
    t, _, r = effect.nearest(res.q)
    assert foot[0] > 2.0 + 1e-4 and foot[2] > 0.0  # rolled out and up the track
    R = res.reactions[: 3 * 7].reshape(-1, 3)
    tangent = effect.curve(t, 1)[0]
    assert abs(R[6] @ tangent) < 1e-9 * np.linalg.norm(R[6]) * np.linalg.norm(tangent)
    # the reactions balance the load to the solution's own tolerance (1e-9 of the forces in play)
    np.testing.assert_allclose(R.sum(axis=0), [0.0, 0.0, 2.0e5], rtol=1e-9, atol=1e-9 * 2.0e5)


def test_a_saved_state_knows_the_curve_it_was_found_on():
    """Nodes on both of two curves (no shift tells them apart): the model's fingerprint still differs, so a
    checkpoint of one is not resumed on the other."""
    from shellform.fingerprint import model_fingerprint

    prints = []
    for middle in ([1.0, 0.0, 0.3], [1.0, 0.0, 0.5]):
        s = Structure([[0.0, 0.0, 0.0], [2.0, 0.0, 0.0]])
        s.add_bars([[0, 1]], EA=1.0)
        s.fix([0])
        s.slide_along([1], [[0.0, 0.0, 0.0], middle, [2.0, 0.0, 0.0]])
        prints.append(model_fingerprint(build_system(s, check=False)))
    assert prints[0]["member properties"] != prints[1]["member properties"]
    assert prints[0]["nodes"] == prints[1]["nodes"]
