"""What one factorisation with the inertia costs on the indentation tangents of the dense hemispheres.

At the pre-stressed state of each n (1 mm Voronoi length, mode I system), the
median of ``--repeat`` numeric refactorisations of the free tangent by

* QDLDL (simplicial LDL^T, AMD ordering): shellform's factor with the inertia;
* CHOLMOD (supernodal Cholesky, through cvxopt): a fresh factorisation, no inertia;
* MKL PARDISO (supernodal LDL^T with Bunch-Kaufman pivoting, ``mtype = -2``,
  through pypardiso) when it is installed: the inertia from ``iparm[21:23]``.

    OPENBLAS_NUM_THREADS=1 MKL_NUM_THREADS=1 python benchmarks/bench_inertia_factor.py --sizes 19 39 49

PARDISO is not a shellform dependency (MKL's wheels are about 200 MB and
x86-only); install ``pypardiso`` beside shellform to get its column.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import scipy.sparse as sp

from bench_ldl_backend import median_time
from shellform.gridshell.hemisphere import HemisphereSpec, build_hemisphere, prestress_on_net
from shellform.gridshell.indentation import indentation_system
from shellform.solvers.cholesky import CholeskyFactor
from shellform.solvers.factor_base import upper_csc


def pardiso_times(K, repeat):
    """Analysis + first factorisation, median refactorisation, and the inertia (positive, negative, perturbed
    pivots) of PARDISO, or None without pypardiso."""
    try:
        import pypardiso
    except ImportError:
        return None
    solver = pypardiso.PyPardisoSolver(mtype=-2)
    upper = sp.triu(K, format="csr")
    rhs = np.zeros((K.shape[0], 1))
    solver.set_phase(12)
    t0 = time.perf_counter()
    solver._call_pardiso(upper, rhs)
    first = time.perf_counter() - t0
    solver.set_phase(22)
    refactor = median_time(lambda: solver._call_pardiso(upper, rhs), repeat)
    return first, refactor, (int(solver.iparm[21]), int(solver.iparm[22]), int(solver.iparm[13]))


def main(argv=None):
    import qdldl

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--sizes", type=int, nargs="+", default=[19, 39])
    p.add_argument("--repeat", type=int, default=3)
    args = p.parse_args(argv)
    print("| n | free | QDLDL refactorisation [s] | CHOLMOD fresh [s] | PARDISO first [s] | PARDISO refactorisation "
          "[s] | PARDISO inertia (+, -, perturbed) |")
    print("|---:|---:|---:|---:|---:|---:|---|")
    for n in args.sizes:
        model = build_hemisphere(HemisphereSpec(n, voronoi_length=1e-3))
        pre = prestress_on_net(model)
        K = indentation_system(model, pre, mode="I").system.tangent_free(pre.q).tocsr()
        U = upper_csc(K)
        ldl = qdldl.Solver(U, upper=True)
        t_ldl = median_time(lambda: ldl.update(U, upper=True), args.repeat)
        t_chol = median_time(lambda: CholeskyFactor(K), args.repeat)
        par = pardiso_times(K, args.repeat)
        cols = ["-", "-", "-"] if par is None else [f"{par[0]:.3f}", f"{par[1]:.3f}", str(par[2])]
        print(f"| {n} | {K.shape[0]} | {t_ldl:.3f} | {t_chol:.3f} | " + " | ".join(cols) + " |", flush=True)


if __name__ == "__main__":
    main()
