"""Rotational springs at rod crossings: derivatives by finite differences, and a scissor against its closed form."""

import numpy as np
import pytest
from scipy.optimize import brentq

from shellform.effects.joint_rotation import JointRotation, angle_derivatives
from shellform.errors import ModelError


def _random_crossings(rng, n=5):
    q = rng.normal(size=3 * 4 * n)
    ends = np.arange(4 * n).reshape(n, 4)
    return q, ends


def test_angle_derivatives_against_finite_differences():
    rng = np.random.default_rng(1)
    u, v = rng.normal(size=(6, 3)), rng.normal(size=(6, 3))
    phi, g, H = angle_derivatives(u, v)
    z = np.concatenate([u, v], axis=1)
    h = 1e-6
    for k in range(6):
        dz = np.zeros(6)
        dz[k] = h
        zp, zm = z + dz, z - dz
        pp, gp, _ = angle_derivatives(zp[:, :3], zp[:, 3:])
        pm, gm, _ = angle_derivatives(zm[:, :3], zm[:, 3:])
        np.testing.assert_allclose((pp - pm) / (2 * h), g[:, k], rtol=1e-7, atol=1e-8)
        np.testing.assert_allclose((gp - gm) / (2 * h), H[:, :, k], rtol=1e-6, atol=1e-7)
    np.testing.assert_allclose(phi, np.arccos(np.einsum("ij,ij->i", u, v) / np.linalg.norm(u, axis=1)
                                               / np.linalg.norm(v, axis=1)), rtol=1e-12)


def test_effect_gradient_and_hessian_against_finite_differences():
    rng = np.random.default_rng(2)
    q0, ends = _random_crossings(rng)
    effect = JointRotation(len(q0), ends, rng.uniform(1.0, 3.0, len(ends)), q0)
    q = q0 + 0.2 * rng.normal(size=q0.shape)
    g = effect.gradient(q)
    rows, cols, vals = effect.hessian(q)
    H = np.zeros((len(q), len(q)))
    np.add.at(H, (rows, cols), vals)
    h = 1e-6
    for k in range(len(q)):
        dq = np.zeros_like(q)
        dq[k] = h
        assert (effect.energy(q + dq) - effect.energy(q - dq)) / (2 * h) == pytest.approx(g[k], rel=1e-6, abs=1e-8)
        np.testing.assert_allclose((effect.gradient(q + dq) - effect.gradient(q - dq)) / (2 * h), H[:, k],
                                   rtol=1e-6, atol=1e-7)
    assert effect.energy(q0) == 0.0 and np.allclose(effect.gradient(q0), 0.0)


def test_parallel_rods_are_refused():
    q = np.array([0, 0, 0, 1, 0, 0, 0, 1, 0, 2, 1, 0], dtype=float)
    with pytest.raises(ModelError, match="parallel"):
        JointRotation(12, [[0, 1, 2, 3]], 1.0, np.array([0, 0, 0, 1, 0, 0, 0, 0, 0, 0, 1, 0.0])).gradient(q)


def _scissor(k, F, ell=1.0, joints="shared"):
    """Two straight steel rods crossing at right angles at their middles, one held at its ends, the other
    turned by a couple of dead forces F at its ends (along x): k theta = 2 F ell' cos theta, the lever
    ell' = ell (1 + F sin theta / EA) stretched by the couple's pull along the turned rod."""
    from shellform.model import Structure
    from shellform.rods import RodNetwork, build_rod_system, circular_section
    from shellform.rods.crossings import crossing_chords

    nodes = [[-ell, 0, 0], [0, 0, 0], [ell, 0, 0], [0, -ell, 0], [0, ell, 0]]
    b = [3, 1, 4]
    if joints == "penalty":
        nodes.append([0, 0, 0])
        b = [3, 5, 4]
    s = Structure(np.array(nodes, dtype=float))
    net = RodNetwork(s)
    sec = circular_section(E=2e11, G=8e10, radius=0.01)
    net.add_rod([0, 1, 2], sec)
    net.add_rod(b, sec)
    if joints == "penalty":
        net.add_joints([[1, 5]])
    s.fix([0, 2])
    s.fix(np.arange(s.n_nodes), "z")
    for rod in net.rods:
        s.fix_dofs(rod.twist_dofs)
    s.add_load([4], [-F, 0.0, 0.0])
    s.add_load([3], [F, 0.0, 0.0])
    ends = crossing_chords(net)
    assert ends.tolist() == [[0, 2, 3, 4]]
    system = build_rod_system(net, extra_effects=[JointRotation(s.n_dof, ends, k, s.reference_state())])
    return s, system, float(sec.EA)


@pytest.mark.parametrize("joints", ["shared", "penalty"])
@pytest.mark.parametrize("load", [0.1, 0.5, 2.0])
def test_a_scissor_turns_as_its_spring_and_the_couple_say(joints, load):
    from shellform.rods.statics import solve_incremental

    k = 10.0
    F = load * k
    s, system, EA = _scissor(k, F, joints=joints)
    res = solve_incremental(system, lam=1.0, n_steps=10)
    assert res.success, res.message
    x = res.q[: 3 * s.n_nodes].reshape(-1, 3)
    top = 4
    theta = np.arctan2(-x[top, 0], x[top, 1])
    exact = brentq(lambda t: k * t - 2 * F * (1 + F * np.sin(t) / EA) * np.cos(t), 0.0, np.pi / 2, xtol=1e-15)
    # to the rounding level of the stiffest springs: the steel rods' axial ones (EA / L = 6e7 N/m), or a
    # penalty joint's, 1e4 times stiffer, whose forces round at 1e-4 of the couple (the acceptance at round-off)
    assert theta == pytest.approx(exact, rel=1e-8 if joints == "shared" else 1e-4)
    # without the spring the scissor is a mechanism
    assert exact > 0.05
