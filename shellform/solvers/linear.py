"""Linear solves behind one small interface.

``factorize(A, method)`` returns an object with ``solve(b)``. Methods:

* ``"direct"`` (default): SuperLU with a symmetric ordering. Works for any
  non-singular matrix, including the indefinite tangents met past a limit point.
* ``"amg"``: conjugate gradients preconditioned by pyamg's smoothed-aggregation
  multigrid. For large symmetric positive definite tangents only (taut rope nets
  and stable states); it reports failure instead of returning a wrong answer.
* ``"auto"``: ``"amg"`` above ``amg_threshold`` unknowns, ``"direct"`` below.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla


class SingularMatrixError(RuntimeError):
    """The matrix could not be factorised or the solve did not converge."""


class DirectFactor:
    """Sparse LU factorisation (SuperLU) of a square matrix."""

    method = "direct"

    def __init__(self, A: sp.spmatrix):
        try:
            # MMD on A^T + A suits the structurally symmetric tangents we build
            self._lu = spla.splu(sp.csc_matrix(A), permc_spec="MMD_AT_PLUS_A")
        except RuntimeError as exc:  # "Factor is exactly singular"
            raise SingularMatrixError(f"sparse LU failed: {exc}") from None

    def solve(self, b: np.ndarray) -> np.ndarray:
        x = self._lu.solve(np.asarray(b, dtype=float))
        if not np.all(np.isfinite(x)):
            raise SingularMatrixError("sparse LU solve produced non-finite values (matrix numerically singular)")
        return x


class AMGFactor:
    """CG with a smoothed-aggregation AMG preconditioner (SPD matrices)."""

    method = "amg"

    def __init__(self, A: sp.spmatrix, rtol: float = 1e-10, maxiter: int = 500):
        import pyamg

        self.A = sp.csr_matrix(A)
        self.rtol = rtol
        self.maxiter = maxiter
        self._ml = pyamg.smoothed_aggregation_solver(self.A, symmetry="symmetric")
        self._M = self._ml.aspreconditioner(cycle="V")

    def solve(self, b: np.ndarray) -> np.ndarray:
        x, info = spla.cg(self.A, b, rtol=self.rtol, maxiter=self.maxiter, M=self._M)
        if info != 0 or not np.all(np.isfinite(x)):
            raise SingularMatrixError(
                f"AMG-preconditioned CG did not converge (info={info}); the matrix may not be positive definite"
            )
        return x


def factorize(A: sp.spmatrix, method: str = "direct", amg_threshold: int = 200_000):
    """Factorise ``A`` for repeated solves.

    Parameters
    ----------
    A : sparse matrix
        Square system matrix.
    method : {"direct", "amg", "auto"}
        See the module docstring.
    amg_threshold : int
        Size above which ``"auto"`` picks AMG.
    """
    if method == "auto":
        method = "amg" if A.shape[0] > amg_threshold else "direct"
    if method == "direct":
        return DirectFactor(A)
    if method == "amg":
        return AMGFactor(A)
    raise ValueError(f"unknown linear solver {method!r}; expected 'direct', 'amg' or 'auto'")
