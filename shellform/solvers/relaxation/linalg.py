"""Linear solves of the implicit scheme: ``(K + sigma M) x = b``, symmetric positive definite.

:class:`SPDSolve` keeps a factorisation from step to step and solves by
conjugate gradients preconditioned with it (:func:`pcg`) while that works,
corrected where the tangent changed (:mod:`.local_correction`); it
refactorises when CG stalls. The number of CG iterations worth an attempt
follows measured cost ratios (:func:`iteration_budget`), not the clock, so a
relaxation takes the same path in every run.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ...errors import ModelError
from ..linear import CholeskyFactor, SingularMatrixError, factorize
from .local_correction import LocalCorrection
from .ordering import dof_order


#: Refactorisation time over the time of one preconditioned CG iteration (a solve with the
#: factor and a product with the matrix) on net tangents of so many unknowns, measured in
#: ``benchmarks/results/bench_factorization.md``: ``(unknowns, ratio)`` points per method.
REFACTOR_COST = {
    "cholesky": ((28_812, 7.6), (295_788, 9.9), (2_988_012, 23.0)),
    "ldl": ((28_812, 22.0), (295_788, 104.0)),
}
#: the ratio assumed for the other methods
OTHER_REFACTOR_COST = 20.0


def iteration_budget(method: str, n: int) -> int:
    """CG iterations worth trying with a kept factor before refactorising a matrix of ``n`` unknowns.

    Half the cost of a refactorisation in iterations (:data:`REFACTOR_COST`,
    interpolated log-log between the measured sizes, constant below the
    smallest, growing as the last two above the largest), between 5 and 60:
    a failed attempt then costs at most half a factorisation. Measured
    sizes, not times of the run, set it, so that a relaxation takes the same
    path in every run.
    """
    points = REFACTOR_COST.get(method)
    if points is None:
        ratio = OTHER_REFACTOR_COST
    else:
        log_n, log_r = np.log(np.array(points, dtype=float)).T
        x = np.log(max(float(n), 1.0))
        if x > log_n[-1]:
            ratio = float(np.exp(log_r[-1] + (x - log_n[-1]) * (log_r[-1] - log_r[-2]) / (log_n[-1] - log_n[-2])))
        else:
            ratio = float(np.exp(np.interp(x, log_n, log_r)))
    return int(round(min(max(0.5 * ratio, 5), 60)))


class SPDSolve:
    """Solves with ``A = K + sigma M`` (symmetric positive definite by construction).

    A factorisation is kept from step to step: the next system is first solved
    by conjugate gradients preconditioned with the old factor (a few cheap
    iterations while the tangent changes little), and refactorised only when
    that does not converge within ``cg_max`` iterations. By default
    ``cg_max`` is half as many iterations as one refactorisation costs
    (:func:`iteration_budget`, a function of the number of unknowns rather
    than of the run's own timings, so that the relaxation takes the same path
    on every run), so a failed attempt never costs more than half a
    factorisation. An attempt pays only while attempts converge more often
    than not: a running estimate of that rate (each attempt weighs 30 %)
    decides, and below one half the old factor is tried only on every fourth
    solve, which keeps the estimate current.

    The old factor is corrected where the matrix has changed since it was
    made (``correct``, :class:`~.local_correction.LocalCorrection`): a rope
    pulled taut or gone slack changes its block by about its whole size and is
    an outlying eigenvalue for the old factor alone; an exact solve on the
    nodes around such ropes takes those out. When too many nodes changed (a
    new stiffness stage changes every entry) the matrix is factorised without
    an attempt.

    Methods: ``"cholesky"`` (what ``"auto"`` means) is CHOLMOD's supernodal
    Cholesky (:class:`~shellform.solvers.linear.CholeskyFactor`) with its
    analysis kept for the fixed pattern (``A`` is positive definite, so no
    inertia and no pivoting are needed); ``"ldl"`` keeps one QDLDL object and
    refactorises numerically on the same pattern; ``"nd"`` factorises with
    SuperLU in a nested-dissection order of the nodes computed once from
    their coordinates (:func:`~.ordering.nested_dissection`; on the
    surface-like graph of a net its fill grows like ``N log N``), with
    explicit zeros (slack ropes) removed first; ``"amg"`` is
    smoothed-aggregation multigrid with the three nodal translations as
    near-null space, for soft nets only (a taut net of nearly inextensible
    ropes is too anisotropic for it). Other methods go to
    :func:`shellform.solvers.linear.factorize`. Their costs across net sizes
    are in ``docs/accuracy.md`` (``benchmarks/bench_factorization.py``).
    """

    def __init__(self, method: str, n: int, reuse: bool = True, cg_max: int | None = None,
                 coords: np.ndarray | None = None, dofs: np.ndarray | None = None, correct: bool = True):
        if method == "auto":
            method = "cholesky"
        if method == "nd" and coords is None:
            raise ModelError("relaxation: the nested-dissection solver needs the node coordinates")
        self.coords = coords
        self.dofs = np.arange(n) if dofs is None else np.asarray(dofs)
        self._perm = None
        self._lu = None
        self.method = method
        self.n = int(n)
        self.reuse = reuse
        self.cg_max = cg_max
        self._qd = None
        self._chol = None
        self._factor = None
        self._ml = None
        self._ready = False
        self.factorizations = 0
        self.cg_iterations = 0
        self.success_rate = 1.0  # running estimate that an attempt with the old factor converges
        self._passed = 0  # solves since the last attempt
        self.correct = correct
        self._kept = None  # the factorised matrix's values, in the order of its pattern
        self._correction = None
        self.corrected = 0  # solves by CG with the kept factor corrected on a changed region

    @property
    def iteration_budget(self) -> int:
        if self.cg_max is not None:
            return int(self.cg_max)
        return iteration_budget(self.method, self.n)

    def _worth_an_attempt(self) -> bool:
        """Whether to try CG with the kept factor before refactorising."""
        if not (self.reuse and self._ready and self.iteration_budget > 0):
            return False
        if self.success_rate >= 0.5 or self._passed >= 3:
            self._passed = 0
            return True
        self._passed += 1
        return False

    def _factorize(self, A: sp.csr_matrix) -> None:
        self._ready = False
        if self.method == "ldl":
            import qdldl

            upper = sp.triu(A, format="csc")
            try:
                if self._qd is None:
                    self._qd = qdldl.Solver(upper)
                else:
                    self._qd.update(upper)
            except (RuntimeError, ValueError) as exc:
                self._qd = None
                raise SingularMatrixError(f"LDL^T factorisation failed: {exc}") from None
        elif self.method == "cholesky":
            try:
                self._chol = CholeskyFactor(A, previous=self._chol)
            except SingularMatrixError:
                self._chol = None
                raise
        elif self.method == "nd":
            import scipy.sparse.linalg as spla

            if self._perm is None:
                self._perm = dof_order(A, self.coords, self.dofs)
            p = self._perm
            self._lu = None  # free the old factor first: two at once would double the peak memory
            Ap = sp.csc_matrix(A[p][:, p])
            # slack ropes leave explicit zeros in the tangent's fixed pattern; SuperLU keeps
            # them in its structure and ran 300 times slower with them (149 s against 0.52 s
            # on the first matrix of a 316 x 316 net, the same nonzeros in the factor)
            Ap.eliminate_zeros()
            try:
                # SPD: no pivoting needed, so the nested-dissection order is kept as given
                self._lu = spla.splu(Ap, permc_spec="NATURAL", diag_pivot_thresh=0.0,
                                     options={"SymmetricMode": True})
            except RuntimeError as exc:
                raise SingularMatrixError(f"sparse factorisation failed: {exc}") from None
        elif self.method == "amg":
            import pyamg

            n = A.shape[0]
            B = np.kron(np.ones((n // 3, 1)), np.eye(3)) if n % 3 == 0 else None
            M = A.tobsr(blocksize=(3, 3)) if n % 3 == 0 else A
            self._ml = pyamg.smoothed_aggregation_solver(M, B=B, symmetry="symmetric", max_coarse=1000)
            self._vcycle = self._ml.aspreconditioner(cycle="V")
        else:
            self._factor = factorize(A, self.method)
        self.factorizations += 1
        self._ready = True
        if self.correct and self.method != "amg":
            self._keep(A)

    def _keep(self, A: sp.csr_matrix) -> None:
        """Remember the factorised values, to find later where a matrix has changed from them."""
        if self._correction is None or not self._correction.fits(A):
            try:
                # three DOFs to a node (rope nets); for other layouts the groups are only coarser or finer
                node_of = np.unique(self.dofs // 3, return_inverse=True)[1]
                self._correction = LocalCorrection(A, node_of) if node_of.size == A.shape[0] else None
            except ValueError:
                self._correction = None
        self._kept = A.data.copy() if self._correction is not None else None

    def _attempt(self, A, b, prec, rtol):
        """Conjugate gradients within the iteration budget; returns ``(x, converged)``."""
        x, ok, its = pcg(A, b, prec, rtol, self.iteration_budget)
        self.cg_iterations += its
        return x, ok

    def _attempt_preconditioner(self, A: sp.csr_matrix):
        """``(preconditioner, corrected)``: the old factor, corrected where ``A`` changed from it.

        The preconditioner is None when a refactorisation is due.
        """
        if self._kept is None or not self._correction.fits(A):
            return self._precondition, False
        prec = self._correction.preconditioner(A, self._kept, self._precondition)
        return prec, prec is not None and prec != self._precondition

    def _precondition(self, b: np.ndarray) -> np.ndarray:
        if self.method == "ldl":
            return self._qd.solve(b)
        if self.method == "cholesky":
            return self._chol.solve(b)
        if self.method == "nd":
            x = np.empty_like(b)
            x[self._perm] = self._lu.solve(b[self._perm])
            return x
        if self.method == "amg":
            return self._vcycle @ b
        return self._factor.solve(b)

    def solve(self, A: sp.csr_matrix, b: np.ndarray, rtol: float) -> np.ndarray:
        """Solve ``A x = b`` to relative residual ``rtol`` (or exactly after a refactorisation)."""
        prec, corrected = self._attempt_preconditioner(A) if self._worth_an_attempt() else (None, False)
        if prec is not None:
            x, ok = self._attempt(A, b, prec, rtol)
            self.success_rate = 0.7 * self.success_rate + 0.3 * float(ok)
            if ok:
                self.corrected += int(corrected)
                return x
        self._factorize(A)
        if self.method == "amg":
            x, ok, its = pcg(A, b, self._precondition, min(rtol, 1e-8), 400)
            self.cg_iterations += its
            if not ok:
                raise SingularMatrixError("AMG-preconditioned CG did not converge")
        else:
            x = self._precondition(b)
            res = b - A @ x
            if float(np.linalg.norm(res)) > rtol * float(np.linalg.norm(b)):
                x = x + self._precondition(res)  # one step of iterative refinement
        if not np.all(np.isfinite(x)):
            self._ready = False
            raise SingularMatrixError("linear solve produced non-finite values")
        return x

def with_values(A: sp.csr_matrix, data: np.ndarray) -> sp.csr_matrix:
    """A CSR matrix of ``A``'s pattern with the values ``data``, sharing its index arrays.

    Only the values of a tangent change from step to step; a full copy would
    also copy the indices, 0.2 s each time at 10^6 nodes.
    """
    return sp.csr_matrix((data, A.indices, A.indptr), shape=A.shape)


def pcg(A, b, prec, rtol, maxiter):
    """Preconditioned conjugate gradients from zero; returns ``(x, converged, iterations)``.

    Every iterate is a descent direction of the quadratic model, so even an
    unconverged result could be used; we still ask for ``rtol``.
    """
    x = np.zeros_like(b)
    r = b.copy()
    nb = float(np.linalg.norm(b))
    if nb == 0.0:
        return x, True, 0
    z = prec(r)
    p = z.copy()
    rz = float(r @ z)
    for k in range(1, maxiter + 1):
        Ap = A @ p
        pAp = float(p @ Ap)
        if not (pAp > 0 and np.isfinite(pAp)):
            return x, False, k
        a = rz / pAp
        x += a * p
        r -= a * Ap
        if float(np.linalg.norm(r)) <= rtol * nb:
            return x, True, k
        z = prec(r)
        rz_new = float(r @ z)
        p = z + (rz_new / rz) * p
        rz = rz_new
    return x, False, maxiter



def diagonal_positions(A: sp.csr_matrix) -> np.ndarray:
    """Index into ``A.data`` of every diagonal entry (all present by construction)."""
    n = A.shape[0]
    rows = np.repeat(np.arange(n), np.diff(A.indptr))
    pos = np.flatnonzero(rows == A.indices)
    if pos.size != n:
        raise ModelError("relaxation: the tangent pattern lacks diagonal entries")
    return pos
