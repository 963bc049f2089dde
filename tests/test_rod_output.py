"""Rod results as written to files: bending moments, torque and axial force against closed forms."""

import meshio
import numpy as np
import pytest

from shellform.effects.rod_output import edge_means
from shellform.io import write_state
from shellform.rods.network import build_rod_system
from shellform.solvers.newton import solve_static
from shellform.validation.cases_rods import clamped_stations, straight_rod


def effect(system, name):
    return next(e for e in system.effects if e.name == name)


def cantilever(P=1e-4, n=20, EI=1.0):
    """Clamped at s = 0, a small transverse tip load P along z: M(s) = P (x_tip - x(s))."""
    s, net = straight_rod(clamped_stations(n), EA=1e6, EI=EI)
    net.clamp(net.rods[0], "start")
    s.add_load([s.n_nodes - 1], [0.0, 0.0, P])
    system = build_rod_system(net)
    res = solve_static(system)
    assert res.success, res.message
    return s, system, res


def test_cantilever_hinge_moments_equal_the_load_times_its_lever_arm():
    P = 1e-4
    s, system, res = cantilever(P)
    x = res.q[: 3 * s.n_nodes].reshape(-1, 3)
    out = effect(system, "rod_bend").member_results(res.q)
    hinge_nodes = np.arange(1, s.n_nodes - 1)
    arm = x[-1, 0] - x[hinge_nodes, 0]
    assert np.allclose(out["bending_moment"], P * arm, rtol=1e-6, atol=0)
    # a load in one plane bends about one material axis only
    M1, M2 = out["bending_moment_1"], out["bending_moment_2"]
    about = np.hypot(M1, M2)
    assert np.allclose(about, P * arm, rtol=1e-6)
    assert np.allclose(np.abs(M1 * M2), 0, atol=1e-9 * P)
    # the root moment, at the clamp (midpoint of the first edge), is P L to the discretisation
    assert out["bending_moment"][0] == pytest.approx(P * (x[-1, 0] - x[1, 0]), rel=1e-6)


def test_written_rod_fields_are_the_hinge_values_at_edge_midpoints(tmp_path):
    P = 1e-4
    s, system, res = cantilever(P)
    mesh = meshio.read(write_state(tmp_path / "c.vtu", system, res.q))
    cd = {k: v[0] for k, v in mesh.cell_data.items()}
    x = res.q[: 3 * s.n_nodes].reshape(-1, 3)
    mid = 0.5 * (x[:-1, 0] + x[1:, 0])
    interior = slice(1, s.n_nodes - 2)  # edges with a hinge at both ends
    assert np.allclose(cd["bending_moment"][interior], P * (x[-1, 0] - mid[interior]), rtol=1e-5)
    for key in ("axial_force", "strain", "bending_moment_1", "bending_moment_2", "curvature_1", "curvature_2",
                "torque", "twist_rate"):
        assert cd[key].shape == (s.n_nodes - 1,) and np.all(np.isfinite(cd[key])), key
    assert "slack" not in cd and "joint_force" not in cd  # nothing computes them here


def test_written_torque_of_a_twisted_rod_is_GJ_phi_over_L(tmp_path):
    GJ, phi, n = 2.0 / 3.0, 0.7, 12
    s, net = straight_rod(clamped_stations(n, both=True), EA=1e6, EI=1.0, GJ=GJ)
    rod = net.rods[0]
    net.clamp(rod, "start")
    net.clamp(rod, "end")
    s.prescribe_dofs([rod.twist_dofs[-1]], [1.0])
    system = build_rod_system(net)
    res = solve_static(system, mu=phi)
    assert res.success, res.message
    cd = meshio.read(write_state(tmp_path / "t.vtu", system, res.q)).cell_data
    assert np.allclose(cd["torque"][0], GJ * phi / 1.0, rtol=1e-9)
    assert np.allclose(cd["twist_rate"][0], phi / 1.0, rtol=1e-9)
    assert np.allclose(cd["bending_moment"][0], 0.0, atol=1e-9)


def test_written_axial_force_of_a_stretched_rod_is_EA_strain(tmp_path):
    EA, n = 50.0, 8
    s, net = straight_rod(np.linspace(0.0, 1.0, n + 1), EA=EA)
    rod = net.rods[0]
    net.pin(rod, "start")
    s.fix([s.n_nodes - 1], "yz")
    s.fix_dofs([rod.twist_dofs[-1]])
    s.add_load([s.n_nodes - 1], [2.0, 0.0, 0.0])
    system = build_rod_system(net)
    res = solve_static(system)
    assert res.success, res.message
    cd = meshio.read(write_state(tmp_path / "a.vtu", system, res.q)).cell_data
    assert np.allclose(cd["axial_force"][0], 2.0, rtol=1e-9)
    assert np.allclose(cd["strain"][0], 2.0 / EA, rtol=1e-9)


def test_edge_means_average_the_hinges_at_both_ends_and_leave_lone_edges_absent():
    hinge_edges = np.array([[0, 1], [1, 2]])
    per_side = np.array([[1.0, 3.0], [5.0, 7.0]])
    assert np.allclose(edge_means(per_side, hinge_edges, 4)[:3], [1.0, 4.0, 7.0])
    assert np.isnan(edge_means(per_side, hinge_edges, 4)[3])
