"""Structured quad grids from gmsh and the NumPy B-spline evaluator."""

import subprocess
import sys

import gmsh
import numpy as np
import pytest
from scipy.interpolate import BSpline

from shellform import ModelError
from shellform.geometry import (
    BSplineSurface,
    basis_functions,
    bspline_surface_grid,
    clamped_uniform_knots,
    dish,
    disk_grid,
    ellipse_grid,
    gmsh_session,
    height_field,
    rectangle_grid,
)


def check_structured(grid):
    ni, nj = grid.shape
    assert grid.n_nodes == ni * nj
    assert len(grid.quads) == (ni - 1) * (nj - 1)
    assert len(grid.edges) == (ni - 1) * nj + ni * (nj - 1)
    # every edge joins structured neighbours
    d = np.abs(grid.ij[grid.edges[:, 1]] - grid.ij[grid.edges[:, 0]]).sum(axis=1)
    assert np.all(d == 1)
    idx = grid.index()
    assert np.all(idx >= 0) and len(np.unique(idx)) == grid.n_nodes
    assert np.array_equal(grid.groups["south"], idx[:, 0])
    assert np.array_equal(grid.groups["west"], idx[0, :])
    assert np.array_equal(grid.groups["corners"], [idx[0, 0], idx[-1, 0], idx[-1, -1], idx[0, -1]])
    assert len(grid.boundary) == 2 * (ni + nj) - 4


def test_rectangle_grid_is_the_structured_lattice():
    g = rectangle_grid(9.0, 4.0, 9, 4, origin=(1.0, 2.0, 3.0))
    check_structured(g)
    assert g.shape == (10, 5)
    # node (i, j) sits at origin + (i dx, j dy)
    expected = np.column_stack([1.0 + g.ij[:, 0] * 1.0, 2.0 + g.ij[:, 1] * 1.0, np.full(g.n_nodes, 3.0)])
    assert np.allclose(g.nodes, expected)
    assert np.allclose(g.nodes[g.groups["ne"][0]], [10.0, 6.0, 3.0])
    # quads counter-clockwise seen from +z
    a, b, d = (g.nodes[g.quads[:, k], :2] for k in (0, 1, 3))
    cross = (b[:, 0] - a[:, 0]) * (d[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (d[:, 0] - a[:, 0])
    assert np.all(cross > 0)
    lengths = np.linalg.norm(g.nodes[g.edges[:, 1]] - g.nodes[g.edges[:, 0]], axis=1)
    assert np.allclose(lengths, 1.0)
    assert set(np.unique(g.edge_direction())) == {0, 1}


@pytest.mark.parametrize("a,b", [(5.0, 5.0), (6.0, 3.0), (2.0, 4.0)])
def test_ellipse_grid_has_its_rim_on_the_ellipse(a, b):
    g = ellipse_grid(a, b, 8, center=(1.0, -1.0, 0.5))
    check_structured(g)
    x, y = g.nodes[:, 0] - 1.0, g.nodes[:, 1] + 1.0
    rho = (x / a) ** 2 + (y / b) ** 2
    assert np.allclose(rho[g.boundary], 1.0, atol=1e-9)
    interior = np.setdiff1d(np.arange(g.n_nodes), g.boundary)
    assert np.all(rho[interior] < 1.0)
    assert np.allclose(g.nodes[:, 2], 0.5)
    # the south-west corner is at -135 degrees
    sw = g.nodes[g.groups["sw"][0]]
    assert np.allclose([sw[0] - 1.0, sw[1] + 1.0], [a * np.cos(np.deg2rad(-135)), b * np.sin(np.deg2rad(-135))])


def test_disk_grid_is_symmetric():
    g = disk_grid(3.0, 10)
    check_structured(g)
    # the grid maps to itself under a quarter turn
    turned = g.nodes[:, [1, 0, 2]] * [-1, 1, 1]
    d = np.linalg.norm(turned[:, None, :] - g.nodes[None, :, :], axis=2).min(axis=1)
    assert d.max() < 1e-9


def test_basis_functions_match_scipy_and_sum_to_one():
    for degree, n in [(1, 4), (2, 5), (3, 7)]:
        k = clamped_uniform_knots(n, degree)
        u = np.linspace(0, 1, 41)
        N = basis_functions(k, degree, u)
        assert np.allclose(N.sum(axis=1), 1.0)
        ref = np.column_stack([BSpline(k, np.eye(n)[i], degree)(u) for i in range(n)])
        # scipy's spline is open at the right end: compare the last point from the left
        ref[-1] = np.column_stack([BSpline(k, np.eye(n)[i], degree)(1 - 1e-14) for i in range(n)])
        assert np.allclose(N, ref, atol=1e-10)
    with pytest.raises(ModelError, match="parameters must lie"):
        basis_functions(clamped_uniform_knots(4, 2), 2, [1.5])


def test_rational_surface_reproduces_a_cylinder():
    # quarter circle as a rational quadratic, extruded linearly along z
    w = np.sqrt(0.5)
    P = np.array([[[1, 0, 0], [1, 0, 2]], [[1, 1, 0], [1, 1, 2]], [[0, 1, 0], [0, 1, 2]]], dtype=float)
    W = np.array([[1, 1], [w, w], [1, 1]])
    s = BSplineSurface(P, degree_u=2, degree_v=1, weights=W)
    X = s.grid(21, 5).reshape(-1, 3)
    assert np.allclose(np.hypot(X[:, 0], X[:, 1]), 1.0)
    assert np.allclose(X[:, 2].reshape(21, 5)[0], np.linspace(0, 2, 5))


def test_height_field_has_linear_precision():
    # a plane through control points at the Greville abscissae is reproduced exactly
    hf = height_field(np.zeros((5, 4)), (0.0, 8.0), (-1.0, 2.0))
    P = hf.surface.control_points
    P[..., 2] = 0.3 * P[..., 0] - 0.7 * P[..., 1] + 2.0
    rng = np.random.default_rng(1)
    x, y = rng.uniform(0, 8, 50), rng.uniform(-1, 2, 50)
    assert np.allclose(hf.z(x, y), 0.3 * x - 0.7 * y + 2.0)
    d = dish((0, 10), (0, 6), depth=1.5)
    assert d.z(5.0, 3.0) == pytest.approx(-1.5)
    assert np.allclose(d.z([0, 10, 5, 5], [3, 3, 0, 6]), 0.0, atol=1e-12)


def test_grid_on_a_bspline_surface_lies_on_it():
    hf = dish((0.0, 10.0), (0.0, 8.0), depth=2.0, n_ctrl=5)
    g = bspline_surface_grid(hf.surface, 10, 8)
    check_structured(g)
    assert g.shape == (11, 9)
    assert np.allclose(g.nodes[:, 2], hf.z(g.nodes[:, 0], g.nodes[:, 1]), atol=1e-9)
    assert np.allclose(g.nodes[g.groups["sw"][0]], [0, 0, 0], atol=1e-9)
    assert np.allclose(g.nodes[g.groups["ne"][0]], [10, 8, 0], atol=1e-9)
    assert g.nodes[:, 2].min() == pytest.approx(-2.0, rel=1e-6)  # the centre node is the bottom


def test_gmsh_is_released_after_errors_and_input_is_checked():
    assert not gmsh.isInitialized()
    with pytest.raises(RuntimeError):
        with gmsh_session():
            raise RuntimeError("boom")
    assert not gmsh.isInitialized()
    with pytest.raises(ModelError, match="side lengths"):
        rectangle_grid(0.0, 1.0, 2, 2)
    with pytest.raises(ModelError, match="positive integer"):
        rectangle_grid(1.0, 1.0, 0, 2)
    with pytest.raises(ModelError, match="semi-axes"):
        ellipse_grid(-1.0, 1.0, 4)
    with pytest.raises(ModelError, match="control points"):
        BSplineSurface(np.zeros((3, 3)))
    assert not gmsh.isInitialized()


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads the signal mask from /proc")
@pytest.mark.parametrize("where", ["main", "thread"])
def test_meshing_leaves_a_broken_pipe_an_error_not_the_end_of_the_process(where):
    """gmsh's first start sets SIGPIPE back to the default that kills the process; gmsh_session undoes it.

    Only the first start in a process does it, so the check runs in a fresh interpreter.
    """
    code = f"""
import threading
from shellform.geometry import rectangle_grid

def ignored():
    mask = next(line for line in open("/proc/self/status") if line.startswith("SigIgn")).split()[1]
    return bool(int(mask, 16) & (1 << 12))

assert ignored()
if {where!r} == "main":
    rectangle_grid(1.0, 1.0, 2, 2)
else:
    thread = threading.Thread(target=rectangle_grid, args=(1.0, 1.0, 2, 2))
    thread.start()
    thread.join()
print(ignored())
"""
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.split() == ["True"]
