"""Stability of an equilibrium from the inertia of its tangent.

An equilibrium is stable when the free-DOF tangent ``K`` is positive definite.
The number of negative eigenvalues of ``K`` (its *inertia*) tells how many
independent directions lower the energy; it changes by one at a simple limit
or bifurcation point. Counting it is more informative than the sign of
``det K``, which cannot see two eigenvalues crossing zero together.

By Sylvester's law of inertia, ``K = P L D L^T P^T`` has as many negative
eigenvalues as ``D`` has negative entries.
:class:`~shellform.solvers.linear.LDLFactor` factorises with ``qdldl`` (AMD
ordering, no pivoting). Without pivoting a factorisation of an
indefinite matrix can meet a zero or tiny pivot or grow large entries, so
:func:`inertia` trusts the count only when every pivot is clearly away from
zero and a test solve has a small backward error. Otherwise it brackets zero
with two shifted factorisations ``K -/+ sigma I`` and resolves the
eigenvalues inside ``[-sigma, sigma)`` with ``eigsh`` in shift-invert mode.

:func:`critical_modes` returns the eigenpairs closest to zero (the buckling
mode at a critical point).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .linear import LDLFactor, SingularMatrixError, shift_diagonal, single_threaded

#: below this size eigenvalue problems are solved densely
DENSE_LIMIT = 400


def start_vector(n: int) -> np.ndarray:
    """The start vector of every Lanczos run: fixed, so that a model gives the same answer run after run
    (ARPACK's own is random), and pseudo-random, so that it is not orthogonal to a symmetric
    structure's antisymmetric modes (a vector of ones would be)."""
    return np.random.default_rng(20261202).standard_normal(n)


#: Lanczos vectors of the first, short attempt of :func:`eigsh_short_first` (and its restarts)
SHORT_BASIS, SHORT_RESTARTS = 6, 2


def eigsh_short_first(A, **kw):
    """``scipy.sparse.linalg.eigsh(A, **kw)`` for one eigenvalue, a short Lanczos basis tried first.

    The eigenvalues shellform asks for one at a time are mostly well apart from
    the rest: the one nearest zero at and next to a critical point, the
    extreme one of the linearised step bound. A short basis finds them in
    5-7 solves against ARPACK's default 20 (on the lattice domes at their
    limit points 3 ms against 13 at 3,711 unknowns, 29-42 against 95 at
    16,131; the step bound's 5 against 10 and 29 against 119 ms at 3,711 and
    16,131). Where the eigenvalues cluster (the soft modes of a pre-stressed
    rod network) a short basis restarts many times (255 solves against 51 at
    the n = 11 hemisphere), so it gets ``SHORT_RESTARTS`` restarts before the
    default basis takes over, 13 solves lost (``benchmarks/bench_lanczos_basis.py``).
    """
    n = A.shape[0]
    if n > 2 * SHORT_BASIS and "ncv" not in kw:
        try:
            return spla.eigsh(A, ncv=SHORT_BASIS, **{**kw, "maxiter": SHORT_RESTARTS})
        except spla.ArpackNoConvergence:
            pass
    return spla.eigsh(A, **kw)


def eigsh_nearest_zero(K, solve, tol: float = 0.0, vectors: bool = False, maxiter: int | None = None):
    """The eigenvalue of ``K`` nearest zero (and its eigenvector): shift-invert Lanczos, ``solve`` applying ``K^-1``.

    Returns ``w`` (one eigenvalue) or ``(w, V)`` (:func:`eigsh_short_first`);
    raises what ``eigsh`` raises.
    """
    n = K.shape[0]
    op = spla.LinearOperator((n, n), matvec=lambda b: solve(np.ravel(b)), dtype=float)
    return eigsh_short_first(K, k=1, sigma=0.0, which="LM", OPinv=op, tol=tol, return_eigenvectors=vectors,
                             v0=start_vector(n), maxiter=maxiter)


class InertiaError(RuntimeError):
    """The inertia of a matrix could not be determined reliably."""


# ---------------------------------------------------------------------------
# inertia
# ---------------------------------------------------------------------------
@dataclass
class Inertia:
    """Eigenvalue sign count of a symmetric matrix.

    Attributes
    ----------
    n_negative, n_zero, n_positive : int
        Eigenvalues below ``-zero_tol``, within ``[-zero_tol, zero_tol]``, above.
    n_below_zero : int
        Eigenvalues strictly below zero, tiny ones included (what a bisection
        on a sign change needs).
    method : str
        ``"ldl"`` (pivot signs), ``"ldl-shifted"`` (two shifted factorisations
        plus eigsh in the band around zero) or ``"dense"``.
    min_pivot_ratio : float
        Smallest pivot of the unshifted factorisation relative to the largest
        diagonal entry (``nan`` when it failed).
    zero_tol : float
        Magnitude below which an eigenvalue counts as zero.
    """

    n_negative: int
    n_zero: int
    n_positive: int
    n_below_zero: int
    method: str
    min_pivot_ratio: float = float("nan")
    zero_tol: float = 0.0


def _diag_scale(A) -> float:
    d = np.abs(A.diagonal())
    s = float(d.max()) if d.size else 0.0
    if s == 0.0:
        s = float(abs(A).max()) if A.nnz else 1.0
    return s


def _dense_inertia(A, zero_tol: float, method: str = "dense", ratio=float("nan")) -> Inertia:
    with single_threaded():
        w = sla.eigvalsh(A.toarray() if sp.issparse(A) else np.asarray(A))
    return Inertia(
        n_negative=int(np.sum(w < -zero_tol)),
        n_zero=int(np.sum(np.abs(w) <= zero_tol)),
        n_positive=int(np.sum(w > zero_tol)),
        n_below_zero=int(np.sum(w < 0.0)),
        method=method,
        min_pivot_ratio=ratio,
        zero_tol=zero_tol,
    )


def _shift_invert_eigsh(A, k: int, sigma: float, vectors: bool):
    """eigsh in shift-invert mode with the inverse from qdldl.

    scipy would factorise ``A - sigma I`` with SuperLU, which is slow on
    shell-like sparsity patterns (tens of seconds at 10^4 DOFs here); the LDL^T
    factor of the shifted matrix does the same job in milliseconds. The shift
    sits just off zero, so ``A - sigma I`` is non-singular even when ``A`` is.
    """
    n = A.shape[0]
    F = LDLFactor(shift_diagonal(A, -sigma))
    op = spla.LinearOperator((n, n), matvec=lambda v: F.solve(np.asarray(v).ravel()), dtype=float)
    return spla.eigsh(sp.csr_matrix(A), k=k, sigma=sigma, which="LM", OPinv=op, return_eigenvectors=vectors,
                      v0=start_vector(A.shape[0]))


def _eigs_near_zero(A, k: int, scale: float) -> np.ndarray:
    """The ``k`` eigenvalues of ``A`` closest to zero."""
    n = A.shape[0]
    if n <= DENSE_LIMIT or k >= n - 1:
        with single_threaded():
            w = sla.eigvalsh(A.toarray())
        return w[np.argsort(np.abs(w))[:k]]
    last = None
    # shift-invert about a point slightly off zero: A itself may be singular
    for offset in (-0.37e-9, 0.53e-9, -0.71e-7, 0.29e-6):
        try:
            w = _shift_invert_eigsh(A, k, offset * scale, False)
            return w[np.argsort(np.abs(w))]
        except (RuntimeError, spla.ArpackNoConvergence, ValueError, SingularMatrixError) as exc:
            last = exc
    raise InertiaError(f"eigsh in shift-invert mode failed near zero: {last}")


def inertia(
    A,
    factor: LDLFactor | None = None,
    pivot_tol: float = 1e-6,
    band: float = 1e-8,
    zero_tol: float | None = None,
    dense_limit: int = 2000,
) -> Inertia:
    """Count the negative, zero and positive eigenvalues of a symmetric matrix.

    Parameters
    ----------
    A : sparse matrix
        Symmetric matrix (the free-DOF tangent).
    factor : LDLFactor or RaisedCholeskyFactor, optional
        An existing factorisation of ``A`` that counts its negative
        eigenvalues (saves refactorising).
    pivot_tol : float
        A pivot smaller than ``pivot_tol`` times the largest diagonal entry may
        hide an eigenvalue near zero (or a loss of accuracy), so the count is
        then checked with shifted factorisations.
    band : float
        Half-width of the band around zero, relative to the largest diagonal
        entry, resolved by shifted factorisations and eigsh.
    zero_tol : float, optional
        Eigenvalues with magnitude up to this count as zero; default
        ``1e-13`` times the largest diagonal entry (a few hundred times the
        rounding level of the eigenvalues).
    dense_limit : int
        Largest size for the last-resort dense eigenvalue count.

    Returns
    -------
    Inertia

    Raises
    ------
    InertiaError
        When neither the factorisations nor the eigenvalue fallbacks succeed.
    """
    A = sp.csr_matrix(A)
    n = A.shape[0]
    scale = _diag_scale(A)
    ztol = 1e-13 * scale if zero_tol is None else float(zero_tol)
    if factor is None:
        try:
            factor = LDLFactor(A)
        except SingularMatrixError:
            factor = None
    ratio = float("nan")
    if factor is not None:
        try:
            ratio = factor.min_pivot_ratio
        except SingularMatrixError:  # a zero pivot, read only now: as if the factorisation had failed
            factor = None
    if factor is not None and factor.trustworthy(pivot_tol):
        m = factor.n_negative_pivots
        return Inertia(m, 0, n - m, m, "ldl", ratio, ztol)

    if n <= DENSE_LIMIT:
        # small: all eigenvalues cost less than two more factorisations
        return _dense_inertia(A, ztol, "dense", ratio)
    found = _shifted_inertia(A, scale, pivot_tol, band, ztol)
    if found is not None:
        found.min_pivot_ratio = ratio
        return found
    if n <= dense_limit:
        return _dense_inertia(A, ztol, "dense", ratio)
    raise InertiaError(
        f"inertia of a {n}x{n} matrix could not be determined: the LDL^T factorisation without pivoting "
        "was unreliable even with shifts"
    )


def _shifted_inertia(A, scale: float, pivot_tol: float, band: float, ztol: float) -> Inertia | None:
    """The inertia from two shifted factorisations bracketing zero, and eigsh inside the bracket.

    ``K + s I`` counts the eigenvalues below ``-s``, ``K - s I`` those below ``+s``;
    the few in between are resolved by eigsh. The band widens tenfold, twice, when a
    bracket cannot be trusted; None when none can.
    """
    n = A.shape[0]
    for rel in (band, 10 * band, 100 * band):
        sigma = rel * scale
        try:
            f_lo = LDLFactor(shift_diagonal(A, sigma))
            f_hi = LDLFactor(shift_diagonal(A, -sigma))
        except SingularMatrixError:
            continue
        # the shifted matrices have no eigenvalue in (-sigma, sigma): their pivots
        # only need to be clear of rounding, not of the band
        shifted_tol = min(pivot_tol, 1e-2 * rel)
        if not (f_lo.trustworthy(shifted_tol) and f_hi.trustworthy(shifted_tol)):
            continue
        below_lo = f_lo.n_negative_pivots  # eigenvalues < -sigma
        below_hi = f_hi.n_negative_pivots  # eigenvalues < +sigma
        m = below_hi - below_lo
        if m < 0:
            continue
        if m == 0:
            return Inertia(below_lo, 0, n - below_lo, below_lo, "ldl-shifted", zero_tol=ztol)
        try:
            w = _eigs_near_zero(A, min(m + 2, n), scale)
        except InertiaError:
            return None
        w = np.sort(w)
        in_band = w[(w >= -sigma) & (w < sigma)]
        if in_band.size != m:
            # eigsh did not return the whole band; try a wider shift
            continue
        n_neg = below_lo + int(np.sum(in_band < -ztol))
        n_zero = int(np.sum(np.abs(in_band) <= ztol))
        return Inertia(
            n_negative=n_neg,
            n_zero=n_zero,
            n_positive=n - n_neg - n_zero,
            n_below_zero=below_lo + int(np.sum(in_band < 0.0)),
            method="ldl-shifted",
            zero_tol=ztol,
        )
    return None


# ---------------------------------------------------------------------------
# critical modes
# ---------------------------------------------------------------------------
def critical_modes(A, k: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """The ``k`` eigenpairs of a symmetric matrix with eigenvalues closest to zero.

    Dense for small matrices, otherwise a few Lanczos iterations of ``eigsh``
    in shift-invert mode about a point just off zero (the matrix itself is
    singular at a critical point).

    Returns
    -------
    values : ndarray, shape (k,)
        Eigenvalues, smallest magnitude first.
    vectors : ndarray, shape (n, k)
        Unit eigenvectors, each with its largest-magnitude entry positive.
    """
    A = sp.csr_matrix(A)
    n = A.shape[0]
    k = int(min(max(k, 1), n))
    if n <= DENSE_LIMIT or k >= n - 1:
        with single_threaded():
            w, V = sla.eigh(A.toarray())
    else:
        scale = _diag_scale(A)
        last = None
        for offset in (-0.37e-9, 0.53e-9, -0.71e-7, 0.29e-6):
            try:
                w, V = _shift_invert_eigsh(A, k, offset * scale, True)
                break
            except (RuntimeError, spla.ArpackNoConvergence, ValueError, SingularMatrixError) as exc:
                last = exc
        else:
            raise InertiaError(f"eigsh in shift-invert mode failed near zero: {last}")
    order = np.argsort(np.abs(w))[:k]
    w, V = w[order], V[:, order]
    idx = np.argmax(np.abs(V), axis=0)
    V = V * np.sign(V[idx, np.arange(V.shape[1])])
    return w, V


#: Lanczos iterations for the eigenvalue nearest zero at a path point (beyond: NaN, not a guess)
EIGENVALUE_ITERATIONS = 200


def nearest_eigenvalue(K, factor=None) -> float:
    """The eigenvalue of a symmetric matrix nearest zero, by Lanczos on its inverse (``factor`` solves with ``K``).

    Dense below ``DENSE_LIMIT`` unknowns. NaN when there is no factor of a
    large matrix (it is singular) or the iteration does not converge: a
    value that was not computed is not reported as one.
    """
    n = K.shape[0]
    if n <= DENSE_LIMIT:
        with single_threaded():
            w = sla.eigvalsh(sp.csr_matrix(K).toarray())
        return float(w[np.argmin(np.abs(w))])
    if factor is None:
        return float("nan")
    op = spla.LinearOperator((n, n), matvec=lambda b: factor.solve(np.ravel(b)), dtype=float)
    try:
        w = spla.eigsh(K, k=1, sigma=0.0, which="LM", OPinv=op, v0=start_vector(n), maxiter=EIGENVALUE_ITERATIONS,
                       tol=1e-8, return_eigenvectors=False)
    except (spla.ArpackNoConvergence, SingularMatrixError, RuntimeError, ValueError):
        return float("nan")
    return float(w[0])


# ---------------------------------------------------------------------------
# rod networks: pivots spanning twelve orders of magnitude
# ---------------------------------------------------------------------------
def count_negative(K) -> int:
    """Negative eigenvalues of a symmetric tangent, from the pivot signs of its LDL^T factorisation.

    Sylvester's law gives the count exactly for an exact factorisation; the
    count is trusted when a test solve has a small backward error (the
    factorisation was stable), whatever the size of the pivots. A rod network
    in SI units has pivots spanning twelve orders of magnitude (penalty
    joints against the twist of a slender rod), so a test on the pivot size
    alone would reject every factorisation. Otherwise :func:`inertia` decides.
    """
    F = None
    try:
        F = LDLFactor(K)
        if F.backward_error() < 1e-11:
            return F.n_negative_pivots
    except SingularMatrixError:
        pass
    try:
        return int(inertia(K, factor=F).n_below_zero)  # the same factor, not a second one
    except InertiaError:
        return -1


def _eigsh_about(K, sigma: float):
    """Eigenpair of ``K`` nearest ``sigma`` by shift-invert Lanczos, inverting with LDL^T."""
    n = K.shape[0]
    A = K if sigma == 0.0 else shift_diagonal(K, -sigma)
    F = LDLFactor(A)
    op = spla.LinearOperator((n, n), matvec=lambda b: F.solve(np.ravel(b)), dtype=float)
    w, V = spla.eigsh(K, k=1, sigma=sigma, which="LM", OPinv=op, tol=1e-9, v0=start_vector(n))
    return float(w[0]), V[:, 0], F


def smallest_eigenpair(K) -> tuple[float, np.ndarray | None]:
    """The algebraically smallest eigenvalue of a symmetric tangent and its unit eigenvector.

    Lanczos in shift-invert mode, the inverse applied with an LDL^T
    factorisation. When ``K`` is positive definite the shift is zero (the
    smallest eigenvalue is the one closest to zero). Otherwise the shift is
    moved below the whole spectrum, checked by Sylvester's law (no negative
    pivot in ``K - sigma I``), so that the eigenvalue nearest the shift is
    the most negative one rather than a soft positive one. The shift is
    never a fraction of the largest diagonal entry: in a rod network the
    softest eigenvalues are twelve orders of magnitude below it. Falls back
    to :func:`critical_modes` when the factorisations fail.
    """
    try:
        lam, v, F = _eigsh_about(K, 0.0)
        negative = F.n_negative_pivots
        del F  # freed, its analysis serves the shifted factorisations below
        if negative == 0 or (lam < 0 and negative == 1):
            return lam, v
        sigma = -2.0 * abs(lam)
        for _ in range(40):
            G = LDLFactor(shift_diagonal(K, -sigma))
            below = G.n_negative_pivots
            del G
            if below == 0:
                lam, v, _ = _eigsh_about(K, sigma)
                return lam, v
            sigma *= 4.0
    except (SingularMatrixError, RuntimeError, spla.ArpackNoConvergence, ValueError):
        pass
    try:
        w, V = critical_modes(K, 1)
        return float(w[0]), V[:, 0]
    except InertiaError:
        return float("nan"), None
