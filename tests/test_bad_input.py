"""Bad models are rejected with a message that names the problem and where it is."""

import numpy as np
import pytest

import shellform as sf
from shellform.errors import MechanismError, ModelError


def square():
    return sf.Structure([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]])


def test_zero_length_member_is_named():
    s = sf.Structure([[0, 0, 0], [1, 0, 0], [1, 0, 0]])
    with pytest.raises(ModelError, match=r"member 1 \(nodes 1-2\) has zero length"):
        s.add_bars([[0, 1], [1, 2]], EA=1.0, name="chords")
    with pytest.raises(ModelError, match="zero length"):
        s.add_ropes([[1, 2]], EA=1.0)


def test_member_to_itself():
    with pytest.raises(ModelError, match="member 0 connects node 2 to itself"):
        square().add_bars([[2, 2]], EA=1.0)


@pytest.mark.parametrize(
    "call",
    [
        lambda s: s.add_bars([[0, 1], [1, 7]], EA=1.0),
        lambda s: s.fix([4]),
        lambda s: s.add_load([-1], [0, 0, 1]),
        lambda s: s.prescribe([10], [0, 0, -1]),
    ],
)
def test_node_index_out_of_range(call):
    with pytest.raises(ModelError, match=r"out of range \(the model has 4 nodes"):
        call(square())


@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_non_finite_coordinate_is_located(bad):
    nodes = np.zeros((3, 3))
    nodes[1] = [1, 0, 0]
    nodes[2, 1] = bad
    with pytest.raises(ModelError, match="coordinate y of node 2 is not finite"):
        sf.Structure(nodes)


def test_bad_properties():
    with pytest.raises(ModelError, match="EA: value of member 1 must be positive"):
        square().add_bars([[0, 1], [1, 2]], EA=[1.0, 0.0])
    with pytest.raises(ModelError, match="EA: value of member 0 is not finite"):
        square().add_bars([[0, 1]], EA=np.nan)
    with pytest.raises(ModelError, match="x, y, z"):
        square().fix([0], "xq")
    with pytest.raises(ModelError, match="slack coefficient"):
        square().add_ropes([[0, 1]], EA=1.0, slack=-2.0)


def test_unsupported_structure_is_a_mechanism():
    s = square()
    s.add_bars([[0, 1], [1, 2], [2, 3], [3, 0], [0, 2]], EA=1.0)
    with pytest.raises(MechanismError, match="can translate freely along x"):
        sf.build_system(s)
    s.fix([0], "z")
    s.fix([1], "z")
    with pytest.raises(MechanismError, match="along x"):
        sf.build_system(s)
    s.fix([0], "xy")
    sf.build_system(s)  # restrained now


def test_loose_node_is_a_mechanism():
    s = square()
    s.add_bars([[0, 1], [1, 2]], EA=1.0)
    s.fix([0, 1, 2])
    with pytest.raises(MechanismError, match=r"node 3 \(not attached to any member\)"):
        sf.build_system(s)


def test_mechanism_stabilised_by_its_load_is_solved_through_the_singular_start():
    # a straight pinned-pinned chain has no transverse stiffness at the start:
    # the tangent is singular, the solver regularises and finds the sagged state
    s = sf.Structure([[0, 0, 0], [1, 0, 0], [2, 0, 0]])
    s.add_bars([[0, 1], [1, 2]], EA=1.0)
    s.fix([0, 2])
    s.fix([1], "y")
    s.add_load([1], [0, 0, -1.0])
    res = sf.solve_static(sf.build_system(s))
    assert res.success, res.message
    assert res.regularised_steps >= 1
    # analytic: 2 N sin(theta) = P with N = EA (1/cos(theta) - 1)
    w = -res.q[5]
    l = np.hypot(1.0, w)
    assert 2 * (l - 1.0) * w / l == pytest.approx(1.0, rel=1e-9)
