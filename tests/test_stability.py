"""Inertia from the LDL^T factorisation (Sylvester's law) against eigenvalues."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from hypothesis import given, settings
from hypothesis import strategies as st
from test_continuation_models import braced_truss, von_mises

from shellform.solvers.linear import LDLFactor, SingularMatrixError
from shellform.solvers.stability import critical_modes, inertia


def reference_counts(A, zero_tol):
    w = np.linalg.eigvalsh(A.toarray())
    return int(np.sum(w < -zero_tol)), int(np.sum(np.abs(w) <= zero_tol)), int(np.sum(w < 0.0))


def random_symmetric(rng, n, density=0.2, diag_scale=1.0):
    A = sp.random(n, n, density, random_state=rng)
    A = A + A.T + sp.diags(diag_scale * rng.standard_normal(n))
    return sp.csr_matrix(A)


def lattice_tangent(m, shift):
    """2D grid Laplacian minus a shift: many negative eigenvalues, clustered spectrum."""
    T = sp.diags([-np.ones(m - 1), 2 * np.ones(m), -np.ones(m - 1)], [-1, 0, 1])
    I = sp.identity(m)
    return sp.csr_matrix(sp.kron(T, I) + sp.kron(I, T) - shift * sp.identity(m * m))


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), n=st.integers(1, 40), tiny_diag=st.booleans())
def test_inertia_matches_dense_eigenvalues(seed, n, tiny_diag):
    rng = np.random.default_rng(seed)
    A = random_symmetric(rng, n, diag_scale=1e-12 if tiny_diag else 1.0)
    I = inertia(A)
    ref = reference_counts(A, I.zero_tol)
    assert (I.n_negative, I.n_zero) == ref[:2]
    assert I.n_negative + I.n_zero + I.n_positive == n


def test_inertia_of_a_large_indefinite_matrix_from_pivots():
    m, shift = 60, 0.35  # 3600 unknowns
    A = lattice_tangent(m, shift)
    I = inertia(A)
    # eigenvalues of the grid Laplacian are known in closed form
    mu = 2.0 - 2.0 * np.cos(np.arange(1, m + 1) * np.pi / (m + 1))
    w = (mu[:, None] + mu[None, :]).ravel() - shift
    assert I.method == "ldl"
    assert I.n_negative == int(np.sum(w < 0)) and I.n_negative > 50


def test_zero_diagonal_needs_the_fallback():
    A = sp.csr_matrix(np.array([[0.0, 1.0], [1.0, 0.0]]))
    with pytest.raises(SingularMatrixError):  # qdldl does not pivot
        LDLFactor(A).n_negative_pivots  # a fresh analysis raises at once, a kept one when the pivots are read
    I = inertia(A)
    assert (I.n_negative, I.n_zero, I.n_positive) == (1, 0, 1)


def test_singular_matrix_reports_zero_eigenvalues():
    A = sp.csr_matrix(np.array([[1.0, 1.0, 0.0], [1.0, 1.0, 0.0], [0.0, 0.0, -2.0]]))
    I = inertia(A)
    assert (I.n_negative, I.n_zero, I.n_positive) == (1, 1, 1)
    assert I.method != "ldl"


def test_tiny_eigenvalue_in_a_large_matrix_resolved_by_shifts_and_eigsh():
    """Eigenvalues at -1e-13 and +3e-9 of the scale: the band around zero is resolved explicitly."""
    m = 25  # 625 unknowns: above the dense limit, so eigsh works on the band
    mu = 2.0 - 2.0 * np.cos(np.arange(1, m + 1) * np.pi / (m + 1))
    lowest = 2.0 * mu[0]
    A = lattice_tangent(m, lowest + 1e-13)  # lowest eigenvalue now -1e-13, the rest clearly positive
    B = sp.block_diag([A, sp.csr_matrix([[3e-9]]), sp.csr_matrix([[-2.0]])], format="csr")
    I = inertia(B)
    assert I.method == "ldl-shifted"
    assert I.n_below_zero == 2  # -1e-13 and -2
    assert I.n_negative == 1  # -2 only: -1e-13 is below the zero tolerance
    assert I.n_zero == 1
    assert I.n_positive == B.shape[0] - 2


def test_ldl_solve_and_symbolic_reuse():
    rng = np.random.default_rng(3)
    A = lattice_tangent(20, 0.1)
    F1 = LDLFactor(A)
    b = rng.standard_normal(A.shape[0])
    assert np.linalg.norm(A @ F1.solve(b) - b) < 1e-10 * np.linalg.norm(b)
    # new values on the same pattern (a symmetric diagonal scaling plus a shift)
    D = sp.diags(1.0 + rng.random(A.shape[0]))
    A2 = sp.csr_matrix(D @ A @ D - 0.2 * sp.identity(A.shape[0]))
    assert np.array_equal(A2.indptr, A.indptr) and np.array_equal(A2.indices, A.indices)
    fresh = LDLFactor(A2)
    reused = LDLFactor(A2, previous=F1)
    assert np.allclose(reused.d, fresh.d, rtol=1e-12)
    assert np.linalg.norm(A2 @ reused.solve(b) - b) < 1e-10 * np.linalg.norm(b)
    assert np.linalg.norm(A2 @ fresh.solve(b) - b) < 1e-10 * np.linalg.norm(b)
    assert fresh.n_negative_pivots == int(np.sum(np.linalg.eigvalsh(A2.toarray()) < 0))


def test_inertia_along_the_von_mises_path_matches_eigenvalues():
    system = von_mises("load", planar=False)  # apex free in x and z
    q = system.q_ref.copy()
    for z in np.linspace(0.5, -0.5, 41):
        q[5] = z
        K = system.tangent_free(q)
        I = inertia(K)
        assert I.n_negative == reference_counts(K, I.zero_tol)[0]


def test_critical_mode_small_and_large():
    system = braced_truss()
    q = system.q_ref.copy()
    K = system.tangent_free(q)
    w, V = critical_modes(K, 2)
    wd, Vd = np.linalg.eigh(K.toarray())
    order = np.argsort(np.abs(wd))[:2]
    assert np.allclose(w, wd[order])
    assert np.allclose(np.abs(V.T @ Vd[:, order]), np.eye(2), atol=1e-10)
    # a matrix large enough for the shift-invert Lanczos path
    A = lattice_tangent(30, 0.0)
    lam_min = spla.eigsh(A, k=1, sigma=0, which="LM", return_eigenvectors=False)[0]
    A = sp.csr_matrix(A - (lam_min + 1e-7) * sp.identity(A.shape[0]))  # singular up to 1e-7
    w, V = critical_modes(A, 1)
    assert abs(w[0] + 1e-7) < 1e-9
    assert np.linalg.norm(A @ V[:, 0] - w[0] * V[:, 0]) < 1e-8
    assert np.max(np.abs(V[:, 0])) == pytest.approx(V[np.argmax(np.abs(V[:, 0])), 0])  # sign convention


def test_inertia_of_the_braced_truss_tangent_near_its_bifurcation():
    """At the analytic bifurcation the out-of-plane stiffness crosses zero: counts 0 | 1 either side."""
    from test_continuation_models import braced_critical

    system = braced_truss()
    (Pb, zb), _ = braced_critical()
    counts = []
    for dz in (1e-6, -1e-6):
        q = system.q_ref.copy()
        q[5] = zb + dz
        counts.append(inertia(system.tangent_free(q)).n_negative)
    assert counts == [0, 1]
