"""Twisting with analytic answers: pure torsion, and Greenhill's twist buckling of a clamped rod."""

import numpy as np
import pytest
from scipy.optimize import brentq

from shellform.model import Structure
from shellform.rods import RodNetwork, RodSection, build_rod_system
from shellform.solvers.newton import solve_static

# clamped-clamped rod under twist: the straight state is lost at M L / EI = 2 x, tan x = x
GREENHILL_CLAMPED = 2 * 4.493409457909064


def twisted_rod(n=40, L=1.0, EI=1.0, GJ=2.0 / 3.0):
    """Both ends clamped, the clamped edges astride s = 0 and s = L; the far clamp turns by
    ``mu`` radians about the axis. The end distance is held, so there is no axial force."""
    l = L / (n - 1)
    st = (np.arange(n + 1) - 0.5) * l
    s = Structure(np.stack([st, 0 * st, 0 * st], axis=1))
    net = RodNetwork(s)
    rod = net.add_rod(np.arange(n + 1), RodSection(EA=1e6, EI=EI, GJ=GJ))
    net.clamp(rod, "start")
    net.clamp(rod, "end")
    s.prescribe_dofs([rod.twist_dofs[-1]], [1.0])
    return s, net, rod, build_rod_system(net)


@pytest.mark.parametrize("phi", [0.5, 4 * np.pi])
def test_end_rotation_gives_torque_GJ_phi_over_L(phi):
    s, net, rod, system = twisted_rod(n=12)
    res = solve_static(system, mu=phi)
    assert res.success, res.message
    torque = res.reactions[rod.twist_dofs[-1]]
    assert torque == pytest.approx(2.0 / 3.0 * phi / 1.0, rel=1e-9)
    # uniform twist, and the opposite torque at the other clamp
    assert res.reactions[rod.twist_dofs[0]] == pytest.approx(-torque, rel=1e-9)
    twist = [e for e in system.effects if e.name == "rod_twist"][0]
    assert np.allclose(twist.member_results(res.q)["torque"], torque, rtol=1e-9)
    assert np.allclose(res.q[: 3 * s.n_nodes], s.nodes.ravel(), atol=1e-12)


def test_twist_buckling_of_a_clamped_rod_from_the_tangent():
    """The lowest eigenvalue of the free tangent of the straight twisted rod crosses zero at
    the critical torque M = 8.9868 EI / L (the mode is a helix: bending coupled to twist
    through the Hessian of the reference twist)."""
    EI, GJ, L = 1.0, 2.0 / 3.0, 1.0
    s, net, rod, system = twisted_rod(EI=EI, GJ=GJ, L=L)

    def lowest(phi):
        res = solve_static(system, mu=phi)
        assert res.success, res.message
        return np.linalg.eigvalsh(system.tangent_free(res.q).toarray())[0], res

    phi_e = GREENHILL_CLAMPED * EI / GJ
    assert lowest(0.9 * phi_e)[0] > 0 > lowest(1.1 * phi_e)[0]
    phi_c = brentq(lambda p: lowest(p)[0], 0.9 * phi_e, 1.1 * phi_e, xtol=1e-9)
    torque = lowest(phi_c)[1].reactions[rod.twist_dofs[-1]]
    assert torque * L / EI == pytest.approx(GREENHILL_CLAMPED, rel=0.01)
    # the buckling mode bends in both transverse directions (a helix), not in one plane
    K = system.tangent_free(lowest(phi_c)[1].q).toarray()
    w, V = np.linalg.eigh(K)
    mode = np.zeros(s.n_dof)
    mode[system.free] = V[:, 0]
    X = mode[: 3 * s.n_nodes].reshape(-1, 3)
    assert np.abs(X[:, 1]).max() > 0.2 * np.abs(X[:, 1:]).max()
    assert np.abs(X[:, 2]).max() > 0.2 * np.abs(X[:, 1:]).max()
