"""Where MKL PARDISO's LDL^T pays against QDLDL's: one factorisation with the inertia, and one solve.

For each model, the median of ``--repeat`` numeric refactorisations (the
analysis of the pattern kept, as in a run) through :class:`LDLFactor` with
each backend, and of one solve (with its refinement against the backward-error
check), on

* the hemisphere's free indentation tangent at the pre-stressed state (mode I,
  1 mm Voronoi length) for each ``--sizes`` n, and the same tangent shifted to
  have a negative eigenvalue (``K - 2 |lambda_min| I``);
* the tangent of a taut n x n rope net plus a mass term (``bench_factorization.py``)
  for each ``--nets`` n;
* the tangent of the apex-loaded lattice dome (``bench_default_path.py``) at the
  located first limit point (one negative eigenvalue), for each ``--domes`` ring count.

The multiply-adds of QDLDL's numeric factorisation (the sum over the columns of its
``L`` of ``c (c + 1)``, ``c`` the column's count) are what it costs: the domes' fill is
several times the hemispheres' at the same size.

    SHELLFORM_LDL=auto python benchmarks/bench_ldl_backend.py --sizes 5 11 19 29 --nets 20 40 80 --domes 10 20 30

Needs pypardiso (``pip install shellform[pardiso]``). MKL runs on one
thread (``shellform.solvers.pardiso.THREADS``).
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))

from shellform.solvers.factor_base import shift_diagonal  # noqa: E402
from shellform.solvers.ldl import LDLFactor  # noqa: E402
from shellform.solvers.stability import smallest_eigenpair  # noqa: E402


def median_time(f, repeat):
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        f()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def row(name, K, repeat):
    b = np.random.default_rng(3).standard_normal(K.shape[0])
    cells = []
    for backend in ("qdldl", "pardiso"):
        F = LDLFactor(K, backend=backend)
        keep = [F]

        def refactor():
            keep[0] = LDLFactor(K, previous=keep[0], backend=backend)

        t_fac = median_time(refactor, repeat)
        t_sol = median_time(lambda: keep[0].solve(b), repeat)
        cells.append((t_fac, t_sol, keep[0].n_negative_pivots, keep[0].backend))
    (q_f, q_s, q_neg, _), (p_f, p_s, p_neg, p_used) = cells
    flops = qdldl_flops(K)
    print(f"| {name} | {K.shape[0]} | {K.nnz} | {flops / 1e6:.1f} | {q_f * 1e3:.1f} | {q_s * 1e3:.1f} | "
          f"{p_f * 1e3:.1f} | {p_s * 1e3:.1f} | {q_f / p_f:.2f} | {q_neg} / {p_neg} ({p_used}) |", flush=True)


def qdldl_flops(K) -> float:
    """Multiply-adds of QDLDL's numeric factorisation: the sum over columns of L of their counts squared."""
    F = LDLFactor(K, backend="qdldl")
    counts = np.diff(F._solver.factors()[0].tocsc().indptr).astype(float)
    return float(np.sum(counts * (counts + 1.0)))


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--sizes", type=int, nargs="*", default=[5, 11, 19, 29])
    p.add_argument("--nets", type=int, nargs="*", default=[20, 40, 80])
    p.add_argument("--domes", type=int, nargs="*", default=[10, 20, 30])
    p.add_argument("--repeat", type=int, default=5)
    args = p.parse_args(argv)
    print("| model | unknowns | entries | QDLDL multiply-adds [10^6] | QDLDL factor [ms] | QDLDL solve [ms] | "
          "PARDISO factor [ms] | PARDISO solve [ms] | factor ratio | negative pivots QDLDL / PARDISO (backend used) |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---|")
    for rings in args.domes:
        from bench_default_path import tangent_past_first_limit

        row(f"lattice dome {rings} rings, past its limit point", tangent_past_first_limit(rings), args.repeat)
    for n in args.nets:
        from bench_factorization import taut_tangent

        K = taut_tangent(n)[0]
        row(f"rope net {n} x {n}", K, args.repeat)
    for n in args.sizes:
        from shellform.gridshell.hemisphere import HemisphereSpec, build_hemisphere, prestress_on_net
        from shellform.gridshell.indentation import indentation_system

        model = build_hemisphere(HemisphereSpec(n, voronoi_length=1e-3))
        pre = prestress_on_net(model)
        K = indentation_system(model, pre, mode="I").system.tangent_free(pre.q).tocsr()
        row(f"hemisphere n = {n}", K, args.repeat)
        lam, _ = smallest_eigenpair(K)
        row(f"hemisphere n = {n}, shifted", shift_diagonal(K, -2.0 * abs(lam)), args.repeat)


if __name__ == "__main__":
    main()
