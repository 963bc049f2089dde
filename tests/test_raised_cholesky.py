"""An indefinite matrix's solves and inertia from a Cholesky factor of it with a few diagonal entries raised."""

import numpy as np
import pytest
import scipy.sparse as sp

from shellform.solvers.factor_base import NotPositiveDefiniteError
from shellform.solvers.raised_cholesky import RaisedCholeskyFactor
from shellform.solvers.stability import inertia


def chain_with_soft_modes(n, eigenvalues, rows):
    """A sparse stiff chain (eigenvalues 0.5 to 4.5) with exact eigenvectors of the given eigenvalues.

    Each soft mode lives on a row and its two neighbours; the chain is projected
    off these modes, so its other eigenvalues stay above 0.5.
    """
    T = sp.diags([-np.ones(n - 1), 2.5 * np.ones(n), -np.ones(n - 1)], [-1, 0, 1]).toarray()
    V = np.zeros((n, len(rows)))
    for k, r in enumerate(rows):
        V[[r - 1, r, r + 1], k] = [0.3, 1.0, -0.2]
    V, _ = np.linalg.qr(V)
    P = np.eye(n) - V @ V.T
    A = P @ T @ P + V @ np.diag(eigenvalues) @ V.T
    A[np.abs(A) < 1e-14] = 0.0
    return sp.csr_matrix(0.5 * (A + A.T))


@pytest.mark.parametrize("negatives", [0, 1, 2])
def test_the_count_and_the_solves_are_those_of_the_matrix_itself(negatives):
    rng = np.random.default_rng(3)
    rows = [40, 120][:max(negatives, 1)]
    eigenvalues = [-0.3, -0.05][:negatives] or [0.2]
    A = chain_with_soft_modes(200, eigenvalues, rows)
    w = np.linalg.eigvalsh(A.toarray())
    assert int(np.sum(w < 0)) == negatives
    F = RaisedCholeskyFactor(A, rows)
    assert F.n_negative_pivots == negatives and F.inertia == (negatives, 0, 200 - negatives)
    assert F.trustworthy(1e-6)
    assert inertia(A, factor=F).n_negative == negatives
    b = rng.standard_normal(200)
    x = F.solve(b)
    np.testing.assert_allclose(A @ x, b, atol=1e-11 * np.abs(b).max())
    np.testing.assert_allclose(F.solve(np.column_stack([b, 2 * b])), np.column_stack([x, 2 * x]), atol=1e-11)


def test_rows_that_miss_a_negative_mode_leave_the_raised_matrix_indefinite():
    A = chain_with_soft_modes(200, [-0.3, -0.05], [40, 120])
    with pytest.raises(NotPositiveDefiniteError):
        RaisedCholeskyFactor(A, [40])  # the second negative mode has nothing at row 40


def test_a_singular_matrix_never_gives_a_trusted_count():
    A = chain_with_soft_modes(100, [0.0], [50])
    F = RaisedCholeskyFactor(A, [50])  # rounding leaves S nonzero, at the level of its cancellation
    assert F.min_pivot_ratio < 1e-12 and not F.trustworthy(1e-10)


def test_a_count_next_to_zero_is_not_trusted():
    """A negative eigenvalue of 1e-9 of the diagonal scale: the count is left to the shifted factorisations."""
    A = chain_with_soft_modes(200, [-1e-9], [60])
    F = RaisedCholeskyFactor(A, [60])
    assert F.n_negative_pivots == 1
    assert not F.trustworthy(1e-6)
    assert inertia(A, factor=F).n_below_zero == 1


def test_rows_are_raised_only_where_they_carry_most_of_the_soft_direction():
    """The rows to raise carry at least half of the path tangent's squared length (the lattice domes'
    apex DOF, 95 %); a direction spread over the structure (the hemisphere's folds, under 2 % in
    three rows) gets none, and its tangents go straight to LDL^T."""
    from shellform.solvers.continuation.problem import MAX_RAISED_ROWS, _rows_to_raise

    rng = np.random.default_rng(8)
    concentrated = 0.01 * rng.standard_normal(500)
    concentrated[17] = 1.0
    assert _rows_to_raise(concentrated)[0] == [17]
    assert all(len(r) <= MAX_RAISED_ROWS and r[0] == 17 for r in _rows_to_raise(concentrated))
    two = 0.01 * rng.standard_normal(500)
    two[[3, 250]] = [0.5, -0.51]
    assert _rows_to_raise(two)[0] == [250, 3]  # one row carries 46 %: two are needed
    assert _rows_to_raise(rng.standard_normal(500)) == []
    assert _rows_to_raise(None) == []
