"""The parametrised equilibrium problem ``G(u, p) = 0`` of one control mode, and its linear algebra.

* ``control="load"``: ``p`` is the load factor ``lam`` multiplying
  ``System.load_vector()``; ``G = System.residual(q, lam)[free]`` and
  ``dG/dp = -f_ref[free]``.
* ``control="displacement"``: ``p`` is the magnitude ``mu`` of the prescribed
  displacements (constrained DOFs at ``q_ref + mu * System.direction``);
  ``dG/dp = (K @ direction)[free]`` with ``K = System.tangent(q)``. The
  generalised reaction conjugate to ``mu`` is ``direction . r(q)``.
"""

from __future__ import annotations

import time

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ...errors import ModelError
from ..factor_base import NotPositiveDefiniteError
from ..linear import CholeskyFactor, LDLFactor, LUFactor, SingularMatrixError
from ..raised_cholesky import RaisedCholeskyFactor


#: Most rows a tangent's diagonal is raised at for a Cholesky factor (and the most negative
#: eigenvalues it is tried for): each attempt that fails costs up to a Cholesky factorisation, and
#: LDL^T takes over after at most this many. Through the star dome's path (up to seven negative
#: eigenvalues) the raised factor served tangents with one and two.
MAX_RAISED_ROWS = 3


#: Least share of the soft direction's squared length the raised rows must carry. Measured on the
#: path tangents next to limit points: 0.947 at the apex's vertical DOF of the lattice domes (the
#: raised factor succeeds), 0.002-0.006 at the largest entry of the hemisphere's and 0.007-0.019 at
#: its three largest (every attempt failed, 39 Cholesky factorisations lost on the n = 19 curve).
MIN_RAISED_SHARE = 0.5


def _rows_to_raise(soft) -> list[list[int]]:
    """Row sets to try raising, by the largest entries of ``soft``: the fewest that carry
    :data:`MIN_RAISED_SHARE` of its squared length, then one more each, up to :data:`MAX_RAISED_ROWS`;
    none where even these many carry less."""
    if soft is None or MAX_RAISED_ROWS == 0:
        return []
    w = np.asarray(soft, dtype=float) ** 2
    total = float(np.sum(w))
    k = min(MAX_RAISED_ROWS, w.size)
    top = np.argpartition(-w, k - 1)[:k]  # the k largest in O(n), then in order
    order = top[np.argsort(-w[top], kind="stable")]
    share = np.cumsum(w[order]) / total if total > 0.0 else np.zeros(order.size)
    if not np.isfinite(share[-1]) or share[-1] < MIN_RAISED_SHARE:
        return []
    first = int(np.searchsorted(share, MIN_RAISED_SHARE)) + 1
    return [[int(i) for i in order[:k]] for k in range(first, order.size + 1)]


class StepFailure(Exception):
    """A corrector did not converge (internal; triggers a cut-back).

    ``singular``: the failure came from a tangent that could not be solved with.
    """

    def __init__(self, message: str, singular: bool = False):
        super().__init__(message)
        self.singular = singular


class LocationFailure(StepFailure):
    """A critical point inside a step could not be located (the step is taken again, shorter)."""


class BranchCrossing(LocationFailure):
    """A point inside a step lies off the path between the step's ends: the end is on another branch."""


class Timer:
    """Wall time by part of the work (the result's ``timings``)."""

    def __init__(self):
        self.t = {"assembly": 0.0, "linear_algebra": 0.0, "stability": 0.0, "event_location": 0.0, "step_bounds": 0.0}

    def add(self, key, t0):
        self.t[key] += time.perf_counter() - t0


class Problem:
    """``G(u, p)`` and its derivatives for one control mode."""

    def __init__(self, system, control, fixed_lam, fixed_mu, timer, linear_solver):
        self.system = system
        self.control = control
        self.fixed_lam = float(fixed_lam)
        self.fixed_mu = float(fixed_mu)
        self.timer = timer
        self.linear_solver = linear_solver
        self.free = system.free
        self.n_free = system.n_free
        self.f_ref = system.load_vector()
        self.f_dead = system.external_force(0.0)
        self._ldl_prev = None
        self._chol_prev = None
        #: called before each factorisation: how many negative eigenvalues the tangent is expected
        #: to have (the last point's count; -1 unknown)
        self.expected_negative = lambda: -1
        #: a Cholesky factorisation, a raised one, failed since the last :meth:`new_point`
        self._cholesky_failed = self._raised_failed = False
        #: called before a raised Cholesky factorisation: a vector along the tangent's softest
        #: direction (None: unknown); the tracer gives the path tangent, which at a limit point
        #: is the critical mode
        self.soft_direction = lambda: None
        #: the rows whose raised diagonal made the last indefinite tangent positive definite
        self._raised_rows = None
        #: every raised attempt at some point failed: the tangents' negative modes are spread out
        #: (the hemisphere's folds), and the attempts would cost a Cholesky factorisation each
        self._raised_declined = False
        self._block = None
        if control == "load":
            if not np.any(self.f_ref != 0.0):
                raise ModelError(
                    "load control: the system has no scaled load (add loads with Structure.add_load(..., scaled=True))"
                )
            self.g_const = -self.f_ref[self.free]
        else:
            d = system.direction
            if system.prescribed.size == 0 or not np.any(d[system.prescribed] != 0.0):
                raise ModelError(
                    "displacement control: no prescribed displacement (use Structure.prescribe with a nonzero direction)"
                )
            self.direction = d

    def lam_mu(self, p):
        return (float(p), self.fixed_mu) if self.control == "load" else (self.fixed_lam, float(p))

    def state(self, u, p):
        _, mu = self.lam_mu(p)
        return self.system.state(u, mu)

    def residual(self, u, p):
        """Free residual, full residual and state."""
        t0 = time.perf_counter()
        q = self.state(u, p)
        lam, _ = self.lam_mu(p)
        r = self.system.residual(q, lam)
        self.timer.add("assembly", t0)
        return r[self.free], r, q

    def _free_block_map(self, K, Kff):
        """Positions in the full CSR data of the entries of the free block."""
        n = K.shape[0]
        full_rows = np.repeat(np.arange(n, dtype=np.int64), np.diff(K.indptr))
        full_key = full_rows * n + K.indices
        order = np.argsort(full_key, kind="stable")
        ff_rows = np.repeat(np.arange(Kff.shape[0], dtype=np.int64), np.diff(Kff.indptr))
        key = self.free[ff_rows] * n + self.free[Kff.indices]
        pos = np.searchsorted(full_key[order], key)
        if np.any(pos >= full_key.size) or np.any(full_key[order][np.minimum(pos, full_key.size - 1)] != key):
            raise RuntimeError("free tangent block not found in the full tangent pattern")
        return order[pos]

    def jacobian(self, u, p, q=None):
        """Free tangent ``K_ff`` and ``dG/dp``."""
        t0 = time.perf_counter()
        if q is None:
            q = self.state(u, p)
        if self.control == "load":
            K = self.system.tangent_free(q)
            g = self.g_const
        else:
            Kfull = self.system.tangent(q)
            if self._block is None or self._block[0] != Kfull.nnz:
                Kff0 = self.system.tangent_free(q)
                self._block = (Kfull.nnz, self._free_block_map(Kfull, Kff0), Kff0.indices, Kff0.indptr)
            _, pos, ind, ptr = self._block
            K = sp.csr_matrix((Kfull.data[pos], ind, ptr), shape=(self.n_free, self.n_free))
            g = (Kfull @ self.direction)[self.free]
        self.timer.add("assembly", t0)
        return K, g

    def factor(self, K):
        """Factorise ``K`` for solves; None when it is singular.

        Where the tangent is expected positive definite, Cholesky (CHOLMOD)
        comes first: it is several times faster than LDL^T on large tangents
        (on the apex-loaded lattice domes 2.1 times at 3,711 unknowns, 5.1 at
        16,131 and 7.2 at 37,209; as fast from 759 up to the hemisphere's
        7,628), and where it succeeds the tangent has no negative eigenvalue.
        Where it fails, or a few negative eigenvalues are expected, Cholesky
        with the diagonal of a few rows raised gives ``K``'s solves and
        inertia (:class:`~shellform.solvers.raised_cholesky.RaisedCholeskyFactor`,
        :meth:`_cholesky`); where that fails too, LDL^T. After a failure the tangents of the same
        point's remaining corrector iterations skip the attempts that failed:
        past a limit point they would fail at each of them.
        """
        t0 = time.perf_counter()
        try:
            if self.linear_solver == "ldl":
                F = self._cholesky(K)
                if F is not None:
                    return F
                try:
                    F = LDLFactor(K, previous=self._ldl_prev)
                    self._ldl_prev = F
                    return F
                except SingularMatrixError:
                    self._ldl_prev = None
            try:
                return LUFactor(K)
            except SingularMatrixError:
                return None
        finally:
            self.timer.add("linear_algebra", t0)

    def _cholesky(self, K):
        """A Cholesky factor of ``K``, or of ``K`` with a few diagonal entries raised; None where neither serves.

        Plain Cholesky while the path is stable. The rows raised are first
        those that served last (kept from a tangent past a critical point until
        the path is stable again, :meth:`path_stable`: the trial points of an
        event's location lie on both sides of it, and the raised factor counts
        either side), then the largest entries of the softest direction the
        tracer knows (the path tangent, along the critical mode next to a limit
        point; :func:`_rows_to_raise`): ``K + E B E^T`` is positive definite
        only if the rows raised carry enough of every negative eigenvalue's
        mode. Where every attempt at a point fails, the run goes on with LDL^T
        alone.
        """
        expected = self.expected_negative()
        if expected < 0 or expected > MAX_RAISED_ROWS or self._raised_failed:
            return None
        if expected == 0 and self._raised_rows is None and not self._cholesky_failed:
            try:
                F = CholeskyFactor(K, previous=self._chol_prev, stored=True)
                self._chol_prev = F
                return F
            except NotPositiveDefiniteError:
                self._cholesky_failed = True  # the analysis stays with the previous factor for the next attempt
        if self._raised_declined:
            return None
        attempts = ([self._raised_rows] if self._raised_rows else []) + _rows_to_raise(self.soft_direction())
        tried = []
        for rows in attempts:
            if set(rows) in tried:
                continue
            tried.append(set(rows))
            try:
                F = RaisedCholeskyFactor(K, rows, previous=self._chol_prev)
            except NotPositiveDefiniteError:
                continue
            except SingularMatrixError:
                break
            self._chol_prev, self._raised_rows = F.cholesky, rows
            return F
        self._raised_failed, self._raised_rows = True, None
        self._raised_declined = bool(tried)
        return None

    def new_point(self) -> None:
        """A new point is sought (a step, a trial point of an event's location): Cholesky may be tried again."""
        self._cholesky_failed = self._raised_failed = False

    def path_stable(self) -> None:
        """The path has come to a point without negative eigenvalues: plain Cholesky again."""
        self._raised_rows = None

    def solve(self, F, b):
        t0 = time.perf_counter()
        try:
            try:
                return F.solve(b)
            except SingularMatrixError:
                # an unpivoted LDL^T of an indefinite matrix may lose accuracy: its
                # solve refines and refuses a poor backward error; then LU decides
                if not isinstance(F, (LDLFactor, RaisedCholeskyFactor)):
                    raise
                return LUFactor(F.A).solve(b)
        finally:
            self.timer.add("linear_algebra", t0)

    def bordered_solve(self, K, g, row_u, row_p, rhs_u, rhs_p, F=None):
        """Solve ``[[K, g], [row_u^T, row_p]] [x; y] = [rhs_u; rhs_p]`` (non-singular at limit points).

        GMRES on the bordered matrix, preconditioned by block elimination with
        a factorisation of ``K`` (of ``K + sigma I`` when ``K`` itself is
        singular): the preconditioned operator is the identity up to a
        low-rank term, so a few iterations suffice and no new sparse
        factorisation of the bordered matrix is needed.
        """
        n = K.shape[0]
        if F is None:
            F = self.factor(K)  # timed by factor itself
        if F is None:
            diag = np.abs(K.diagonal())
            sigma = 1e-10 * float(diag.max(initial=1.0))
            F = self.factor(sp.csr_matrix(K + sigma * sp.identity(n, format="csr")))
        t0 = time.perf_counter()
        try:
            rhs = np.concatenate([rhs_u, [rhs_p]])
            if F is not None:
                try:
                    Ag = F.solve(g)
                    schur = row_p - float(row_u @ Ag)
                    if schur != 0.0 and np.isfinite(schur):

                        def precond(v):
                            Af = F.solve(v[:n])
                            y = (v[n] - float(row_u @ Af)) / schur
                            return np.concatenate([Af - y * Ag, [y]])

                        def matvec(v):
                            return np.concatenate([K @ v[:n] + g * v[n], [float(row_u @ v[:n]) + row_p * v[n]]])

                        M = spla.LinearOperator((n + 1, n + 1), matvec=matvec, dtype=float)
                        P = spla.LinearOperator((n + 1, n + 1), matvec=precond, dtype=float)
                        x0 = precond(rhs)
                        sol, info = spla.gmres(M, rhs, x0=x0, M=P, rtol=1e-12, atol=0.0, restart=20, maxiter=5)
                        res = float(np.max(np.abs(matvec(sol) - rhs)))
                        # normwise backward error of the bordered system
                        norm_m = float(abs(K).sum(axis=1).max()) + float(np.max(np.abs(g))) + float(
                            np.sum(np.abs(row_u)) + abs(row_p))
                        scale = norm_m * float(np.max(np.abs(sol))) + float(np.max(np.abs(rhs)))
                        if np.all(np.isfinite(sol)) and res <= 1e-10 * max(scale, 1e-300):
                            return sol[:n], float(sol[n])
                except SingularMatrixError:
                    pass
            # last resort: a sparse LU of the bordered matrix
            Mb = sp.bmat(
                [[K, sp.csr_matrix(g.reshape(-1, 1))], [sp.csr_matrix(row_u.reshape(1, -1)), sp.csr_matrix([[row_p]])]],
                format="csc",
            )
            sol = LUFactor(Mb).solve(rhs)
            return sol[:n], float(sol[n])
        finally:
            self.timer.add("linear_algebra", t0)

    def load_measure(self, r, p):
        if self.control == "load":
            return float(p)
        return float(self.direction @ r)  # only constrained entries of direction are nonzero

    def external_norm(self, p):
        lam, _ = self.lam_mu(p)
        return float(np.linalg.norm(self.f_dead + lam * self.f_ref))


def factor_alive(F) -> bool:
    """Whether a factor can still solve (a later factorisation may have taken its storage)."""
    if F is None:
        return False
    if isinstance(F, RaisedCholeskyFactor):
        return F.alive
    if getattr(F, "_solver", True) is None or getattr(F, "_symbolic", True) is None:
        return False
    return not getattr(F, "_stale", False)
