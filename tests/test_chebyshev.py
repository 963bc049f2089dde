"""The Chebyshev net of the hemispherical gridshell."""

import numpy as np
import pytest

from shellform.errors import ModelError
from shellform.geometry.chebyshev import _compass_net, chebyshev_hemisphere

R = 0.0382  # 2R = 7.64 cm (the gridshell paper's hemisphere, shellform.gridshell.hemisphere.PAPER)


@pytest.fixture(scope="module")
def net5():
    return chebyshev_hemisphere(R, 5)


def test_compass_net_is_a_chebyshev_net_on_the_sphere():
    delta = R / 20
    P = _compass_net(R, delta, 25)
    chord = 2 * R * np.sin(0.5 * delta / R)
    ok = np.all(np.isfinite(P), axis=2)
    assert np.allclose(np.linalg.norm(P[ok], axis=1), R, rtol=1e-12)
    # every edge of the net, along both families, has the same length
    for axis in (0, 1):
        d = np.linalg.norm(np.diff(P, axis=axis), axis=2)
        d = d[np.isfinite(d)]
        assert d.size > 1000
        assert np.allclose(d, chord, rtol=1e-10)


def test_central_rods_are_half_great_circles(net5):
    for family in ("u", "v"):
        rod = net5.rod(family, 0)
        assert rod.length == pytest.approx(np.pi * R, rel=1e-12)
        assert rod.s_end == pytest.approx(0.5 * np.pi * R, rel=1e-12)
    assert net5.spacing == pytest.approx(np.pi * R / 6)


def test_rods_end_on_the_equator_and_stay_on_the_sphere(net5):
    for rod in net5.rods:
        assert rod.points[0, 2] == pytest.approx(0.0, abs=1e-15)
        assert rod.points[-1, 2] == pytest.approx(0.0, abs=1e-15)
        assert np.all(rod.points[1:-1, 2] > 0)
        # the cut ends interpolate a chord of length delta: off the sphere by O(delta^2 / R)
        assert np.allclose(np.linalg.norm(rod.points, axis=1), R, atol=net5.delta**2 / R)


def test_the_two_families_mirror_each_other(net5):
    for k in range(-2, 3):
        u, v = net5.rod("u", k), net5.rod("v", k)
        assert u.length == pytest.approx(v.length, rel=1e-12)
        assert np.allclose(u.points[:, [1, 0, 2]], v.points, atol=1e-14)
        # and rod k mirrors rod -k
        assert u.length == pytest.approx(net5.rod("u", -k).length, rel=1e-12)


def test_joints_sit_at_multiples_of_the_spacing_along_both_rods(net5):
    h = net5.spacing
    assert len(net5.joints) >= 20
    for j in net5.joints:
        on_u = net5.rod("u", j.u_index).position(j.v_index * h)
        on_v = net5.rod("v", j.v_index).position(j.u_index * h)
        assert np.allclose(on_u, j.position, atol=1e-15)
        assert np.allclose(on_v, j.position, atol=1e-15)


def test_footprint_is_a_square_grid_of_straight_rods(net5):
    h = net5.spacing
    for rod, ends in zip(net5.rods, net5.footprint()):
        assert np.allclose(np.linalg.norm(ends[1] - ends[0]), rod.length)
        offset = ends[:, 1] if rod.family == "u" else ends[:, 0]
        assert np.allclose(offset, rod.index * h)


def test_rod_lengths_converge_with_the_construction_step():
    lengths = [chebyshev_hemisphere(R, 5, delta=np.pi * R / 6 / m).rod("u", 2).length for m in (16, 32, 64)]
    e1, e2 = abs(lengths[0] - lengths[2]), abs(lengths[1] - lengths[2])
    assert e2 < e1 / 3  # at least first-order convergence towards the smooth net
    assert e2 < 1e-4 * lengths[2]


@pytest.mark.parametrize("kwargs, words", [
    (dict(radius=-1.0, n=5), "radius must be positive"),
    (dict(radius=R, n=4), "positive odd integer"),
    (dict(radius=R, n=5, spacing=0.05), "beyond the equator"),
])
def test_bad_parameters(kwargs, words):
    with pytest.raises(ModelError, match=words):
        chebyshev_hemisphere(**kwargs)
