"""Joints between rods: the penalty spring of Eq. (3) and the exact shared node."""

import numpy as np
import pytest
from helpers import all_finite
from fd import dense_hessian, fd_gradient, fd_jacobian, relative_error

from shellform.effects.joints import PenaltyJoints
from shellform.errors import ModelError
from shellform.model import Structure
from shellform.rods import RodNetwork, RodSection, build_rod_system, stack_polylines
from shellform.solvers.newton import solve_static


def test_penalty_joint_gradient_and_hessian():
    rng = np.random.default_rng(0)
    q = rng.normal(size=18)
    eff = PenaltyJoints(18, [[0, 1], [2, 5], [3, 4]], [1.0, 10.0, 3.0])
    assert relative_error(eff.gradient(q), fd_gradient(eff.energy, q)) < 1e-8
    assert relative_error(dense_hessian(eff, q), fd_jacobian(eff.gradient, q)) < 1e-8
    gap = eff.member_results(q)["gap"]
    assert gap[1] == pytest.approx(np.linalg.norm(q[6:9] - q[15:18]))


def grid(merge, ratio=1e4, n_rods=3, n_edges=12, L=1.0):
    """Three rods along x over three along y, crossing at nine joints, ends pinned,
    vertical loads on the crossings."""
    c = np.linspace(0, L, n_rods + 2)[1:-1]
    x = np.linspace(0, L, n_edges + 1)
    lines = [np.stack([x, 0 * x + ci, 0 * x], 1) for ci in c] + [np.stack([0 * x + ci, x, 0 * x], 1) for ci in c]
    nodes, idx, pairs = stack_polylines(lines, merge=merge)
    s = Structure(nodes)
    net = RodNetwork(s)
    for ix in idx:
        net.add_rod(ix, RodSection(EA=1e4, EI=1.0, GJ=0.75))
    if not merge:
        net.add_joints(pairs, stiffness_ratio=ratio)
    for r in range(len(idx)):
        net.pin(r, "start")
        net.pin(r, "end")
    on_x_rods = np.concatenate(idx[:n_rods])
    crossing = on_x_rods[np.isin(np.round(s.nodes[on_x_rods, 0], 9), np.round(c, 9))]
    s.add_load(crossing, [0.0, 0.0, -1.0])
    return s, net, idx, pairs


def test_joint_stiffness_is_relative_to_the_rods():
    s, net, idx, pairs = grid(merge=False, ratio=1.0)
    # every joint node sits on edges of EA / L = 1e4 / (1/12)
    assert np.allclose(net.joint_reference_stiffness(pairs), 1.2e5)
    assert np.allclose(net.joint_stiffness, 1.2e5)
    with pytest.raises(ModelError, match="itself"):
        net.add_joints([[3, 3]])


def test_penalty_from_1e2_to_1e8_converges_and_gaps_shrink():
    load = 60.0
    s0, net0, idx0, _ = grid(merge=True)
    shared = solve_static(build_rod_system(net0), lam=load)
    assert shared.success, shared.message
    x_shared = shared.q[: 3 * s0.n_nodes].reshape(-1, 3)
    deflection = np.abs(x_shared[:, 2]).max()
    assert deflection > 0.05  # well into the nonlinear range (span 1)
    gaps, errors = [], []
    for ratio in 10.0 ** np.arange(2, 9):
        s, net, idx, pairs = grid(merge=False, ratio=ratio)
        res = solve_static(build_rod_system(net), lam=load)
        assert res.success, (ratio, res.message)
        assert res.iterations <= 8
        assert all_finite(res.q)
        x = res.q[: 3 * s.n_nodes].reshape(-1, 3)
        gaps.append(np.linalg.norm(x[pairs[:, 0]] - x[pairs[:, 1]], axis=1).max())
        # the first rod's nodes are numbered alike in both models
        errors.append(np.abs(x[idx[0]] - x_shared[idx0[0]]).max())
    gaps, errors = np.array(gaps), np.array(errors)
    # the gap is the joint force over K_s: it falls tenfold per decade of penalty
    assert np.allclose(gaps[1:] / gaps[:-1], 0.1, rtol=0.02), gaps
    # the penalty solution approaches the shared-node one until round-off takes over
    assert np.all(errors[1:5] < 0.2 * errors[:4]), errors
    assert errors.max() < 1e-4 * deflection, errors


def test_written_joint_forces_share_each_crossing_load_between_the_rods(tmp_path):
    """x-rods and y-rods are alike, so the crossing (a, b) of the x-rod at y = b and the
    y-rod at x = a mirrors the crossing (b, a): what the joint at (a, b) passes on plus what
    the joint at (b, a) passes on is one crossing's load, and half of it on the diagonal
    (small load: the joint forces are vertical). Joints are written as cells of their own;
    the rod fields there are absent (NaN), and the joint fields absent on the rods."""
    import meshio

    from shellform.io import write_state

    load = 1e-3
    s, net, idx, pairs = grid(merge=False, ratio=1e6)
    system = build_rod_system(net)
    res = solve_static(system, lam=load)
    assert res.success, res.message
    cd = {k: v[0] for k, v in meshio.read(write_state(tmp_path / "j.vtu", system, res.q)).cell_data.items()}
    joint = cd["group"] == -1
    assert joint.sum() == len(pairs)
    force = dict(zip(map(tuple, np.round(s.nodes[pairs[:, 0], :2], 9)), cd["joint_force"][joint]))
    for (a, b), f in force.items():
        assert f + force[(b, a)] == pytest.approx(load, rel=1e-5)
    assert force[(0.5, 0.5)] == pytest.approx(0.5 * load, rel=1e-5)
    assert np.all(np.isnan(cd["joint_force"][~joint])) and np.all(np.isnan(cd["torque"][joint]))
    assert np.all(np.isfinite(cd["torque"][~joint]))
