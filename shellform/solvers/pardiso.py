"""MKL PARDISO's supernodal LDL^T with its inertia: the backend of :class:`~shellform.solvers.ldl.LDLFactor`
for large matrices.

QDLDL factorises column by column (simplicial); PARDISO eliminates dense
supernodes with BLAS kernels in a nested-dissection (METIS) ordering. One
numeric refactorisation with the analysis kept, one thread each
(``benchmarks/results/bench_ldl_backend.md``, n = 39 from
``bench_inertia_factor.md``):

=====================  =========  ==========  ===========
model                  unknowns   QDLDL [ms]  PARDISO [ms]
=====================  =========  ==========  ===========
hemisphere n = 5       3,688      0.8         1.4
hemisphere n = 11      7,628      3.0         3.6
hemisphere n = 19      12,924     25.4        8.1
hemisphere n = 29      19,512     208         17.5
hemisphere n = 39      26,036     1,751       45
rope net 40 x 40       4,332      5.8         3.2
rope net 80 x 80       18,252     49.5        18.7
=====================  =========  ==========  ===========

hence :data:`MIN_SIZE`. What decides is the fill, not the size: QDLDL's
multiply-adds (the sum over the columns of its ``L`` of ``c (c + 1)``) are
0.5 and 4.7 million for the n = 5 and 11 hemispheres, but 19 million for the
20-ring lattice dome (3,711 unknowns), where PARDISO takes 3.8 ms against
QDLDL's 10.2; PARDISO was faster on every pattern measured from 10^7
multiply-adds up and slower below 5 x 10^6, except the 10-ring dome by
0.4 ms (``bench_ldl_backend.md``). But loading MKL costs a process about
1 s once: the 20-ring dome's run to its first limit point (10 LDL^T
factorisations) took 1.2 s in a fresh process with PARDISO against 0.3 s
with QDLDL, although 0.15 s against 0.18 s once MKL was loaded. The load is
repaid within a run where a factorisation saves some 20 ms, from about
5 x 10^7 multiply-adds (the 30-ring dome: 8.4 x 10^7, 33 against 12 ms).
Below :data:`MIN_SIZE`, ``auto`` therefore sends a pattern to PARDISO when
QDLDL's factorisation of it costs :data:`MIN_MULTIPLY_ADDS` or more,
measured once per pattern before any of its factors is used (so that a
pattern's backend does not depend on what ran before it). The whole mode-I indentation curve of the n = 19
hemisphere took 16-18 s against 25 s with QDLDL alone, with the same
thresholds, steps and Newton iterations; n = 39 took 122 s against 948 s.

PARDISO is an optional dependency (``pip install shellform[pardiso]``:
MKL's wheels are about 200 MB and x86 only). Which backend an
:class:`LDLFactor` uses is its ``backend`` argument or, by default, the
environment variable ``SHELLFORM_LDL``:

* ``auto`` (default): PARDISO from :data:`MIN_SIZE` unknowns up, and for
  smaller patterns whose QDLDL factorisation costs :data:`MIN_MULTIPLY_ADDS`
  or more, when pypardiso can be imported; QDLDL otherwise;
* ``qdldl``: always QDLDL;
* ``pardiso``: PARDISO for every nonempty matrix (an error without pypardiso).

Trust first. A PARDISO factor is used only when its inertia can be taken at
face value: no pivot was perturbed (``iparm[13] == 0``), every pivot is
finite and nonzero, and the signs of the pivots agree with PARDISO's own
counts. Otherwise :class:`LDLFactor` factorises the same matrix with QDLDL,
which raises :class:`SingularMatrixError` where it always did; and a PARDISO
factor whose solve fails the backward-error check is replaced by QDLDL's
for that matrix in the same way.

``iparm`` is indexed from 0 here, as in C and NumPy: ``iparm[k]`` is the
manual's Fortran ``iparm(k+1)``.
"""

from __future__ import annotations

import ctypes
import os

import numpy as np
import scipy.sparse as sp

from .ldl import _SymbolicPool

#: environment variable choosing the backend of every LDLFactor
BACKEND_VARIABLE = "SHELLFORM_LDL"
BACKENDS = ("auto", "qdldl", "pardiso")

#: ``auto`` uses PARDISO from this many unknowns up (see the module docstring)
MIN_SIZE = 10_000
#: ... and below it for a pattern whose QDLDL factorisation costs this many multiply-adds or more
#: (see the module docstring: PARDISO is faster from 10^7, but repays MKL's load only from about here)
MIN_MULTIPLY_ADDS = 5.0e7

#: MKL threads of a PARDISO call. One, like the dense solves under
#: :func:`~shellform.solvers.factor_base.single_threaded`: the reference machine has two cores, the
#: figures above are single-threaded, and studies run one process per core. With one thread MKL is
#: loaded with its sequential layer (unless ``MKL_THREADING_LAYER`` says otherwise); the count is also
#: set for the calling thread around each call (``mkl_set_num_threads_local``) and restored after it.
THREADS = 1

# matrix type: real symmetric indefinite
_MTYPE = -2

_LIB = None  # mkl_rt, loaded on first use
_AVAILABLE = None
_INSTALLED = None


def _library():
    """mkl_rt as pypardiso finds it; imported on first use only (pypardiso's package import builds a solver)."""
    global _LIB
    if _LIB is None:
        from pypardiso.pardiso_wrapper import PyPardisoSolver

        _bind_cholmod_blas()

        lib = PyPardisoSolver().libmkl
        lib.pardiso.restype = None
        lib.pardiso_getdiag.restype = None
        lib.MKL_Set_Num_Threads_Local.restype = ctypes.c_int
        lib.MKL_Set_Num_Threads_Local.argtypes = [ctypes.c_int]
        if THREADS == 1 and not os.environ.get("MKL_THREADING_LAYER"):
            # MKL's sequential layer, chosen before its first call: no OpenMP runtime is started (see
            # _bind_cholmod_blas: a library whose BLAS calls reach MKL would run them on its threads)
            lib.MKL_Set_Threading_Layer.restype = ctypes.c_int
            lib.MKL_Set_Threading_Layer.argtypes = [ctypes.c_int]
            lib.MKL_Set_Threading_Layer(1)  # MKL_THREADING_SEQUENTIAL
        _LIB = lib
    return _LIB


def _bind_cholmod_blas() -> None:
    """Let CHOLMOD (cvxopt) bind its BLAS and LAPACK calls before MKL is loaded.

    MKL's layers export the plain BLAS names (``dgemm_``, ``dsyrk_``, ...) to
    the whole process, and a shared library binds each such call the first
    time it makes it: a CHOLMOD that factorised nothing supernodal before MKL
    was loaded calls MKL's BLAS instead of the OpenBLAS it ships with. Over
    the n = 19 hemisphere curve its 335 factorisations then took 7.1 s
    instead of 3.1 s (MKL's OpenMP threads on the 2 cores) and one at the
    pre-stressed state 13-14 ms instead of 9 ms with MKL's sequential layer.
    One small dense factorisation and solve (0.5 ms) bind them to OpenBLAS.
    """
    try:
        from .cholesky import CholeskyFactor
    except ImportError:
        return
    n = 96  # dense: supernodal, its BLAS and LAPACK calls all made
    A = np.full((n, n), 0.5) + n * np.eye(n)
    try:
        F = CholeskyFactor(sp.csr_matrix(A))
        F.solve(np.ones(n))
        F.solve(np.ones((n, 2)))
    except Exception:  # CHOLMOD missing or failing: nothing to bind
        pass


def available() -> bool:
    """Whether pypardiso and its MKL library can be loaded (checked once)."""
    global _AVAILABLE
    if _AVAILABLE is None:
        try:
            _library()
            _AVAILABLE = True
        except (ImportError, OSError, AttributeError):
            _AVAILABLE = False
    return _AVAILABLE


def backend_choice() -> str:
    """The value of ``SHELLFORM_LDL`` (``auto`` when unset), checked."""
    choice = os.environ.get(BACKEND_VARIABLE, "").strip().lower() or "auto"
    if choice not in BACKENDS:
        raise ValueError(f"{BACKEND_VARIABLE}={os.environ.get(BACKEND_VARIABLE)!r} is not a backend of the LDL^T "
                         f"factorisation; expected one of {', '.join(BACKENDS)}")
    return choice


def installed() -> bool:
    """Whether pypardiso is installed (without loading MKL, which :func:`available` does)."""
    global _INSTALLED
    if _INSTALLED is None:
        import importlib.util

        _INSTALLED = importlib.util.find_spec("pypardiso") is not None
    return _INSTALLED


def use_pardiso(n: int, backend: str | None = None, multiply_adds=None) -> bool:
    """Whether an LDL^T factorisation of ``n`` unknowns goes to PARDISO.

    ``backend`` is one of :data:`BACKENDS`; None reads ``SHELLFORM_LDL`` (see the module docstring).
    ``multiply_adds``: a callable giving QDLDL's cost of the pattern (or None), asked for only where it
    decides, below :data:`MIN_SIZE` with pypardiso installed.
    """
    choice = backend_choice() if backend is None else backend
    if choice not in BACKENDS:
        raise ValueError(f"unknown LDL^T backend {choice!r}; expected one of {', '.join(BACKENDS)}")
    if choice == "qdldl" or n == 0:
        return False
    if choice == "pardiso":
        if not available():
            raise ImportError(f"{BACKEND_VARIABLE}=pardiso needs pypardiso (pip install shellform[pardiso])")
        return True
    if n >= MIN_SIZE:
        return available()
    if multiply_adds is None or not installed():
        return False
    cost = multiply_adds()
    return cost is not None and cost >= MIN_MULTIPLY_ADDS and available()


def _iparm() -> np.ndarray:
    """PARDISO's integer parameters, 0-based, for symmetric indefinite tangents."""
    iparm = np.zeros(64, dtype=np.int32)
    iparm[0] = 1    # the values below are given (0 would fill in MKL's defaults and ignore them)
    iparm[1] = 2    # fill-in reducing ordering: nested dissection (METIS)
    iparm[7] = 0    # no iterative refinement inside PARDISO: LDLFactor.solve refines against its own check
    # Pivots below 10^-13 ||A||_inf are perturbed (MKL's default for symmetric indefinite matrices, 10^-8,
    # would perturb the pivots of rod networks, which span twelve orders of magnitude in SI units). A
    # perturbed factor is not used at all (trust first), so this only decides when QDLDL takes over.
    iparm[9] = 13
    # No scaling and no weighted matching (iparm[10] = iparm[12] = 0). Both would be worked out from the
    # values of the analysed matrix and kept for the whole pattern, and the pivots would be those of the
    # scaled matrix: min_pivot_ratio (relative to A's own diagonal) would change its meaning.
    iparm[10] = 0
    iparm[12] = 0
    # 1x1 diagonal pivoting inside the supernodes, not Bunch-Kaufman's 1x1 and 2x2 blocks: D is then
    # diagonal and pardiso_getdiag returns its pivots d, whose signs give the inertia (checked against
    # iparm[22]) and whose smallest magnitude min_pivot_ratio. The tangents are factorised by QDLDL
    # without any pivoting, so 1x1 pivoting is already more stable; where it is not enough a pivot is
    # perturbed and QDLDL decides.
    iparm[20] = 0
    iparm[23] = 0   # classic factorisation (the two-level one pays off on many threads)
    iparm[24] = 0   # sequential forward and backward solve
    iparm[26] = 0   # no matrix checker (the upper triangle comes sorted from upper_csc)
    iparm[27] = 0   # double precision
    iparm[34] = 1   # zero-based ia and ja: scipy's arrays are passed as they are
    iparm[55] = 1   # keep the factor's diagonal for pardiso_getdiag
    return iparm


#: output parameters (0-based)
_PERTURBED, _POSITIVE, _NEGATIVE = 13, 21, 22


class PardisoError(RuntimeError):
    """PARDISO returned an error code."""


class _Pool(_SymbolicPool):
    """Freed PARDISO solvers kept by pattern with their analysis (each also holds its factor's memory:
    fewer than QDLDL's).

    A solver whose memory was released is never handed out: when the
    garbage collector frees a reference cycle holding an LDLFactor and its
    solver, it runs both finalisers in either order, the factor's giving the
    solver back to the pool and the solver's releasing its memory.
    """

    size = 2

    def give(self, U, solver) -> None:
        if solver._live:
            super().give(U, solver)

    def take(self, U):
        # the collector may also finalise a solver after its factor gave it back: it is dropped here
        while (solver := super().take(U)) is not None and not solver._live:
            pass
        return solver


_POOL = _Pool()


class PardisoSolver:
    """One PARDISO instance: the analysis of one sparsity pattern and the factor of its latest values.

    Offers what :class:`~shellform.solvers.ldl.LDLFactor` uses of a qdldl
    solver (``update``, ``solve``) plus the pivots and PARDISO's counts. Its
    memory is released (phase -1) when it is freed.

    Parameters
    ----------
    U : scipy.sparse.csc_matrix
        Upper triangle of the symmetric matrix in CSC form with the whole
        diagonal stored (:func:`~shellform.solvers.factor_base.upper_csc`).
    """

    #: where a freed LDLFactor gives this solver back
    pool = _POOL

    def __init__(self, U: sp.csc_matrix):
        self.lib = _library()
        n = U.shape[0]
        self.n = n
        # PARDISO reads the upper triangle row by row (CSR); the CSC arrays of U are its lower triangle's
        # rows. Where the entries of U go in CSR order is worked out once for the pattern.
        order = sp.csc_matrix((np.arange(U.nnz, dtype=float), U.indices, U.indptr), shape=U.shape).tocsr()
        order.sort_indices()
        self._order = order.data.astype(np.int64)
        self._ia = order.indptr.astype(np.int32)
        self._ja = order.indices.astype(np.int32)
        self._a = np.asarray(U.data, dtype=float)[self._order]
        self._pt = np.zeros(64, dtype=np.int64)
        self.iparm = _iparm()
        self._perm = np.zeros(n, dtype=np.int32)
        self._live = True  # PARDISO's memory is released from here on (phase -1), whatever happens
        self.d = np.zeros(0)
        self._call(11)  # ordering and symbolic factorisation
        self.factorize()

    # -- PARDISO calls ------------------------------------------------------------------------
    def _call(self, phase: int, b: np.ndarray | None = None) -> np.ndarray | None:
        if not self._live:
            raise PardisoError("this PARDISO instance's memory was released")
        i32 = ctypes.c_int32
        p32 = ctypes.POINTER(i32)
        nrhs = 1 if b is None or b.ndim == 1 else b.shape[1]
        if b is None:
            b = x = np.zeros(1)
        else:
            b = np.asfortranarray(b, dtype=float)
            x = np.zeros_like(b, order="F")
        err = i32(0)
        previous = self.lib.MKL_Set_Num_Threads_Local(THREADS)
        try:
            self.lib.pardiso(self._pt.ctypes.data_as(ctypes.POINTER(ctypes.c_int64)), ctypes.byref(i32(1)),
                             ctypes.byref(i32(1)), ctypes.byref(i32(_MTYPE)), ctypes.byref(i32(phase)), ctypes.byref(i32(self.n)),
                             self._a.ctypes.data_as(ctypes.c_void_p), self._ia.ctypes.data_as(p32),
                             self._ja.ctypes.data_as(p32), self._perm.ctypes.data_as(p32), ctypes.byref(i32(nrhs)),
                             self.iparm.ctypes.data_as(p32), ctypes.byref(i32(0)), b.ctypes.data_as(ctypes.c_void_p),
                             x.ctypes.data_as(ctypes.c_void_p), ctypes.byref(err))
        finally:
            self.lib.MKL_Set_Num_Threads_Local(previous)
        if err.value != 0:
            raise PardisoError(f"PARDISO phase {phase} returned error {err.value}")
        return x

    def factorize(self) -> None:
        """Numeric factorisation of the values held (phase 22) and the pivots of D."""
        self.d = np.zeros(0)
        self._call(22)
        df = np.zeros(self.n)
        da = np.zeros(self.n)
        err = ctypes.c_int32(0)
        self.lib.pardiso_getdiag(self._pt.ctypes.data_as(ctypes.c_void_p), df.ctypes.data_as(ctypes.c_void_p),
                                 da.ctypes.data_as(ctypes.c_void_p), ctypes.byref(ctypes.c_int32(1)),
                                 ctypes.byref(err))
        if err.value != 0:
            raise PardisoError(f"pardiso_getdiag returned error {err.value}")
        self.d = df

    def update(self, U: sp.csc_matrix, upper: bool = True) -> None:
        """Refactorise new values on the analysed pattern (no new analysis)."""
        self._a = np.asarray(U.data, dtype=float)[self._order]
        self.factorize()

    def solve(self, b: np.ndarray) -> np.ndarray:
        """``A^{-1} b`` (phase 33), one right-hand side or one per column."""
        b = np.asarray(b, dtype=float)
        return np.ascontiguousarray(self._call(33, b))

    # -- what the factor tells ----------------------------------------------------------------
    @property
    def n_perturbed(self) -> int:
        return int(self.iparm[_PERTURBED])

    @property
    def n_negative(self) -> int:
        return int(self.iparm[_NEGATIVE])

    @property
    def n_positive(self) -> int:
        return int(self.iparm[_POSITIVE])

    def trusted(self) -> bool:
        """Whether the pivot signs are the inertia: none perturbed, all finite and nonzero, signs agreeing
        with PARDISO's counts."""
        d = self.d
        return (self.n_perturbed == 0 and d.size == self.n and bool(np.all(np.isfinite(d))) and not np.any(d == 0.0)
                and int(np.count_nonzero(d < 0.0)) == self.n_negative
                and self.n_negative + self.n_positive == self.n)

    # -- memory ---------------------------------------------------------------------------------
    def release(self) -> None:
        """Free PARDISO's memory of this instance (phase -1)."""
        if self._live:
            try:
                self._call(-1)
            except PardisoError:
                pass
            finally:
                self._live = False

    def __del__(self):
        try:
            self.release()
        except Exception:  # at interpreter shutdown the process frees everything anyway
            pass


def factor(U: sp.csc_matrix, previous=None) -> PardisoSolver | None:
    """A trusted PARDISO factor of the matrix whose upper triangle is ``U``, or None.

    The analysis comes from ``previous`` (an LDLFactor whose PARDISO solver
    has the same pattern: it gives its storage to the new factor), else from
    a freed factor's solver of the pattern, else it is made. None when the
    factor cannot be trusted (:meth:`PardisoSolver.trusted`) or PARDISO
    fails; the solver then goes back to the pool with its analysis, for the
    next matrix of the pattern.
    """
    if not np.all(np.isfinite(U.data)):
        return None  # QDLDL's factorisation reports it
    solver = None
    held = getattr(previous, "_solver", None)
    if isinstance(held, PardisoSolver) and held._live and held.n == U.shape[0] and np.array_equal(
            previous._U.indptr, U.indptr) and np.array_equal(previous._U.indices, U.indices):
        solver, previous._solver = held, None
    if solver is None:
        solver = _POOL.take(U)
    try:
        if solver is not None:
            solver.update(U)
        else:
            solver = PardisoSolver(U)
    except PardisoError:
        if solver is not None and solver._live:
            _POOL.give(U, solver)
        return None
    if solver.trusted():
        return solver
    _POOL.give(U, solver)
    return None
