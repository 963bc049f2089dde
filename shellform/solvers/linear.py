"""Linear solves behind one small interface.

``factorize(A, method)`` returns an object with ``solve(b)``. Methods:

* ``"direct"`` (default): sparse LDL^T (QDLDL with AMD ordering) for the
  symmetric tangents shellform assembles; when it meets a zero pivot or its
  solution fails a backward-error check, SuperLU LU with partial pivoting takes
  over. Measured on a 148k-DOF rope-net tangent: QDLDL 6.6 s, SuperLU 150 s
  (``benchmarks/bench_assembly.py``). The LDL^T factor (:class:`LDLFactor`,
  the same one :mod:`shellform.solvers.stability` and the continuation use)
  also gives the inertia (number of negative eigenvalues, Sylvester's law); with
  pypardiso installed, large ones are MKL PARDISO's (:mod:`shellform.solvers.pardiso`).
* ``"ldl"``, ``"lu"``: one of the two, without fallback.
* ``"cholesky"``: supernodal Cholesky (CHOLMOD) for symmetric positive
  definite matrices, several times faster than LDL^T on large ones
  (:class:`CholeskyFactor`); it fails instead of returning an inertia.
* ``"amg"``: conjugate gradients preconditioned by pyamg's smoothed-aggregation
  multigrid. For large symmetric positive definite tangents only (taut rope nets
  and stable states); it reports failure instead of returning a wrong answer.
* ``"auto"``: ``"amg"`` above ``amg_threshold`` unknowns, ``"direct"`` below.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .cholesky import CholeskyFactor
from .factor_base import SingularMatrixError, shift_diagonal, single_threaded
from .ldl import LDLFactor

__all__ = ["CholeskyFactor", "LDLFactor", "LUFactor", "SingularMatrixError", "factorize", "shift_diagonal",
           "single_threaded"]


class LUFactor:
    """Sparse LU factorisation with partial pivoting (SuperLU)."""

    method = "lu"

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


class DirectFactor:
    """LDL^T where it works, LU where it does not (see the module docstring)."""

    method = "direct"

    def __init__(self, A: sp.spmatrix):
        self._ldl = None
        try:
            self._ldl = LDLFactor(A)
            self._impl = self._ldl
        except SingularMatrixError:
            self._impl = LUFactor(A)

    def solve(self, b: np.ndarray) -> np.ndarray:
        try:
            return self._impl.solve(b)
        except SingularMatrixError:
            if self._impl is not self._ldl:
                raise
            self._impl = LUFactor(self._ldl.A)
            return self._impl.solve(b)


class AMGFactor:
    """CG with a smoothed-aggregation AMG preconditioner (SPD matrices)."""

    method = "amg"

    def __init__(self, A: sp.spmatrix, rtol: float = 1e-10, maxiter: int = 500):
        import pyamg

        self.A = sp.csr_matrix(A)
        self.rtol = rtol
        self.maxiter = maxiter
        n = self.A.shape[0]
        if n % 3 == 0:
            # nodal unknowns come in xyz triples: aggregate by node and keep the
            # three translations in the coarse spaces (near-null space of a net)
            B = np.kron(np.ones((n // 3, 1)), np.eye(3))
            self._ml = pyamg.smoothed_aggregation_solver(self.A.tobsr(blocksize=(3, 3)), B=B, symmetry="symmetric")
        else:
            self._ml = pyamg.smoothed_aggregation_solver(self.A, symmetry="symmetric")
        #: one V-cycle as a linear operator, for callers running their own Krylov method
        self.preconditioner = self._ml.aspreconditioner(cycle="V")

    def solve(self, b: np.ndarray) -> np.ndarray:
        x, info = spla.cg(self.A, b, rtol=self.rtol, maxiter=self.maxiter, M=self.preconditioner)
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
    method : {"direct", "ldl", "lu", "cholesky", "amg", "auto"}
        See the module docstring.
    amg_threshold : int
        Size above which ``"auto"`` picks AMG.
    """
    if method == "auto":
        method = "amg" if A.shape[0] > amg_threshold else "direct"
    if method == "direct":
        return DirectFactor(A)
    if method == "ldl":
        return LDLFactor(A)
    if method == "lu":
        return LUFactor(A)
    if method == "cholesky":
        return CholeskyFactor(A)
    if method == "amg":
        return AMGFactor(A)
    raise ValueError(f"unknown linear solver {method!r}; expected 'direct', 'ldl', 'lu', 'cholesky', 'amg' or 'auto'")
