"""Sparse factorisations of a taut rope-net tangent: QDLDL LDL^T against CHOLMOD Cholesky.

The nets are those of ``bench_mra.py`` (n x n masses, 30 m square, rim hung)
in a state where every rope is taut (the planform stretched by 20 % with a
random sag), so the tangent has its full pattern. The matrix is the one the
implicit relaxation factorises, ``K + m / h^2``. For each size the same
matrix is factorised by

* QDLDL (``LDLFactor``): the first factorisation (ordering, symbolic and
  numeric) and a numeric refactorisation on the same pattern;
* CHOLMOD (``CholeskyFactor``): the same two;

followed by one solve with each factor; the timings are the best of
``--repeat`` runs. Writes ``benchmarks/results/bench_factorization.{md,json}``.

Run:  python benchmarks/bench_factorization.py [--sizes 32 100 316] [--repeat 3]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # the relaxation benchmark runs single-threaded too

import argparse  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import scipy.sparse as sp  # noqa: E402
from results_table import write_results  # noqa: E402



def taut_tangent(n: int) -> sp.csr_matrix:
    """``K + m / h^2`` of an n x n net of bench_mra.py with every rope taut."""
    from bench_mra import make_net

    from shellform.solvers.relaxation import nodal_masses

    system = make_net(n).system()
    q = system.q_ref.copy()
    q *= 1.2
    q[2::3] += 0.3 * np.random.default_rng(1).standard_normal(q[2::3].shape)
    K = system.tangent_free(q)
    m = np.repeat(nodal_masses(system), 3)[system.free]  # one mass per node, on each of its translations
    h = 1.0  # a pseudo step of the converging stages
    return sp.csr_matrix(K + sp.diags(m / h**2))


def best(fn, repeat: int) -> tuple[float, object]:
    out, t_best = None, np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        t_best = min(t_best, time.perf_counter() - t0)
    return t_best, out


def measure(n: int, repeat: int) -> dict:
    from shellform.solvers.linear import CholeskyFactor, LDLFactor

    A = taut_tangent(n)
    b = np.random.default_rng(2).standard_normal(A.shape[0])
    row = {"nodes": n * n, "unknowns": A.shape[0], "nonzeros": int(A.nnz)}
    for name, cls, kwargs in (("qdldl", LDLFactor, {"check": None}), ("cholmod", CholeskyFactor, {})):
        t_first, F = best(lambda: cls(A, **kwargs), repeat)
        holder = [F]

        def refactor():
            holder[0] = cls(1.0001 * A, previous=holder[0], **kwargs)
            return holder[0]

        t_re, F = best(refactor, repeat)
        t_solve, x = best(lambda: F.solve(b), repeat)
        err = float(np.linalg.norm(1.0001 * (A @ x) - b) / np.linalg.norm(b))
        row.update({f"{name}_first_s": t_first, f"{name}_refactor_s": t_re, f"{name}_solve_s": t_solve,
                    f"{name}_relative_residual": err})
    row["refactor_ratio"] = row["qdldl_refactor_s"] / row["cholmod_refactor_s"]
    return row


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="*", default=[32, 100, 316], help="nodes per side")
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args(argv)
    rows = [measure(n, args.repeat) for n in args.sizes]
    lines = ["| nodes | unknowns | QDLDL first [s] | QDLDL refactor [s] | CHOLMOD first [s] | CHOLMOD refactor [s] "
             "| refactor ratio | QDLDL solve [s] | CHOLMOD solve [s] |",
             "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['nodes']} | {r['unknowns']} | {r['qdldl_first_s']:.3f} | {r['qdldl_refactor_s']:.3f} | "
                     f"{r['cholmod_first_s']:.3f} | {r['cholmod_refactor_s']:.3f} | {r['refactor_ratio']:.1f} | "
                     f"{r['qdldl_solve_s']:.4f} | {r['cholmod_solve_s']:.4f} |")
    load = os.getloadavg()
    lines += ["", f"Best of {args.repeat} runs; load average at the end {load[0]:.2f} (2 cores, shared). "
              f"Command: `python benchmarks/bench_factorization.py --sizes {' '.join(map(str, args.sizes))}`."]
    write_results("bench_factorization", lines, rows)


if __name__ == "__main__":
    import sys

    sys.path.insert(0, str(Path(__file__).resolve().parent))
    main()
