"""Continuum limit: nets converge to the small-slope membrane (equal force densities on a square grid,
cotangent force densities on triangles)."""

import numpy as np
import pytest

from shellform.assembly import build_system
from shellform.mra.membrane import force_density_net, force_density_solve, membrane_centre_deflection
from shellform.solvers.relaxation import relax

SQUARE_COEFFICIENT = 0.0736714  # small-slope membrane on a square, w_max = c p a^2 / N (reference.MEMBRANE_SQUARE_COEFFICIENT)


@pytest.fixture(scope="module")
def continuum():
    return membrane_centre_deflection(refine=5)


def test_fem_membrane_matches_the_analytic_coefficient(continuum):
    assert continuum == pytest.approx(SQUARE_COEFFICIENT, rel=2e-6)


def test_nets_converge_to_the_membrane_at_second_order(continuum):
    errors = []
    for n in (4, 8, 16, 32):
        s, grid, centre = force_density_net(n)
        system = build_system(s)
        res = relax(system, scheme="implicit", rtol=1e-10)
        assert res.success, res.message
        w = -res.q[3 * centre + 2]
        # the MRA relaxation solves exactly the linear force-density problem (force density q (1 - 1e-9))
        w_fd = force_density_solve(n)[n // 2 - 1, n // 2 - 1]
        assert w == pytest.approx(w_fd, rel=1e-8)
        # in-plane positions stay on the planform grid (horizontal equilibrium of equal force densities)
        assert np.max(np.abs(res.q.reshape(-1, 3)[:, :2] - grid.nodes[:, :2])) < 1e-10
        errors.append(abs(w - continuum) / continuum)
    ratios = np.array(errors[:-1]) / np.array(errors[1:])
    assert np.all((ratios > 3.6) & (ratios < 4.4))  # error ~ h^2
    assert errors[-1] < 1e-3


def test_explicit_relaxation_of_the_membrane_net():
    s, grid, centre = force_density_net(6)
    system = build_system(s)
    fast = relax(system, scheme="implicit", rtol=1e-9)
    slow = relax(system, scheme="rk4", rtol=1e-9)
    assert slow.success
    assert np.max(np.abs(slow.q - fast.q)) < 1e-8


def _relaxed_unstructured(h, elements, equal=False):
    from shellform.geometry.planforms import polygon_planform
    from shellform.mra.membrane import deflection_at, membrane_force_densities, unstructured_force_density_net

    g = polygon_planform([(0, 0), (1, 0), (1, 1), (0, 1)], edge_length=h, elements=elements)
    faces = g.triangles if elements == "triangles" else g.quads
    if elements == "triangles":
        edges, q, area = membrane_force_densities(g.nodes, g.triangles)
    else:  # the quads gmsh makes of a square are a regular grid: equal force densities, a quarter of each quad
        edges = g.edges
        p = g.nodes[g.quads]
        quad_area = 0.5 * np.linalg.norm(np.cross(p[:, 2] - p[:, 0], p[:, 3] - p[:, 1]), axis=1)
        area = np.bincount(g.quads.ravel(), weights=np.repeat(quad_area / 4, 4), minlength=g.n_nodes)
        q = np.ones(len(edges))
    if equal:
        q = np.ones(len(edges))
    res = relax(build_system(unstructured_force_density_net(g.nodes, edges, q, area, g.boundary)),
                scheme="implicit", rtol=1e-10, start="reference")
    assert res.success, res.message
    return deflection_at(g.nodes, faces, -res.q.reshape(-1, 3)[:, 2], (0.5, 0.5))


@pytest.mark.parametrize("elements", ["triangles", "quads"])
def test_unstructured_nets_converge_to_the_membrane_at_second_order(continuum, elements):
    """Triangles need the cotangent force densities (the linear finite elements of the membrane);
    the quads gmsh makes of a square take equal ones."""
    errors = [abs(_relaxed_unstructured(h, elements) - continuum) / continuum for h in (1 / 8, 1 / 16, 1 / 32)]
    ratios = np.array(errors[:-1]) / np.array(errors[1:])
    assert np.all((ratios > 3.5) & (ratios < 4.7)), errors  # error ~ h^2
    assert errors[-1] < 1.5e-3


def test_equal_force_densities_on_triangles_find_another_surface(continuum):
    """About three ropes per node: the net is stiffer than the membrane it is meant to be, by a factor
    near sqrt(3) on nearly equilateral triangles, at every mesh size."""
    for h in (1 / 8, 1 / 16, 1 / 32):
        ratio = continuum / _relaxed_unstructured(h, "triangles", equal=True)
        assert 1.5 < ratio < 2.0
