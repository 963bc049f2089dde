"""Sparse factorisations of a taut rope-net tangent: QDLDL LDL^T against CHOLMOD Cholesky.

The nets are those of ``bench_mra.py`` (n x n masses, 30 m square, rim hung)
in a state where every rope is taut (the planform stretched by 20 % with a
random sag), so the tangent has its full pattern. The matrix is the one the
implicit relaxation factorises, ``K + m / h^2``. For each size the same
matrix is factorised by

* QDLDL (``LDLFactor``): the first factorisation (ordering, symbolic and
  numeric) and a numeric refactorisation on the same pattern;
* CHOLMOD (``CholeskyFactor``): the same two;
* CHOLMOD in a nested-dissection order of the nodes computed from their
  coordinates (:func:`shellform.solvers.relaxation.nested_dissection`)
  instead of its own approximate minimum degree (AMD): the analysis with
  that order, a numeric refactorisation, and the time to compute the order;

followed by one solve with each factor; the timings are the best of
``--repeat`` runs. QDLDL runs on ``--qdldl-sizes`` only (at 1000 x 1000 nodes
it would take hours). The growth exponent of CHOLMOD's refactorisation
between consecutive sizes shows what one step of the relaxation costs as the
net grows; the peak memory is the process's after each size (sizes run from
small to large). Writes ``benchmarks/results/bench_factorization.{md,json}``.

Run:  python benchmarks/bench_factorization.py [--sizes 32 100 316 1000] [--qdldl-sizes 32 100 316] [--repeat 3]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # the relaxation benchmark runs single-threaded too

import argparse  # noqa: E402
import resource  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import scipy.sparse as sp  # noqa: E402
from results_table import write_results  # noqa: E402



def taut_tangent(n: int) -> tuple[sp.csr_matrix, np.ndarray, np.ndarray]:
    """``K + m / h^2`` of an n x n net of bench_mra.py with every rope taut, the state and the free DOFs."""
    from bench_mra import make_net

    from shellform.solvers.relaxation import nodal_masses

    system = make_net(n).system()
    q = system.q_ref.copy()
    q *= 1.2
    q[2::3] += 0.3 * np.random.default_rng(1).standard_normal(q[2::3].shape)
    K = system.tangent_free(q)
    m = np.repeat(nodal_masses(system), 3)[system.free]  # one mass per node, on each of its translations
    h = 1.0  # a pseudo step of the converging stages
    return sp.csr_matrix(K + sp.diags(m / h**2)), q, system.free


def best(fn, repeat: int) -> tuple[float, object]:
    out, t_best = None, np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        t_best = min(t_best, time.perf_counter() - t0)
    return t_best, out


def nested_dissection_cholesky(A: sp.csr_matrix, order: np.ndarray):
    """CHOLMOD's analysis of ``A`` in the elimination order ``order``; returns ``(matrix, analysis)``."""
    from cvxopt import cholmod, matrix, spmatrix

    U = sp.triu(A, format="coo")
    M = spmatrix(matrix(U.data), matrix(U.row.astype(np.int64)), matrix(U.col.astype(np.int64)), A.shape)
    return M, cholmod.symbolic(M, uplo="U", p=matrix(order.astype(np.int64)))


def factor_times(name: str, cls, kwargs: dict, A: sp.csr_matrix, b: np.ndarray, repeat: int) -> dict:
    """First factorisation, numeric refactorisation and solve of ``A`` with the factor class ``cls``."""
    t_first, F = best(lambda: cls(A, **kwargs), repeat)
    holder = [F]

    def refactor():
        holder[0] = cls(1.0001 * A, previous=holder[0], **kwargs)
        return holder[0]

    t_re, F = best(refactor, repeat)
    t_solve, x = best(lambda: F.solve(b), repeat)
    err = float(np.linalg.norm(1.0001 * (A @ x) - b) / np.linalg.norm(b))
    return {f"{name}_first_s": t_first, f"{name}_refactor_s": t_re, f"{name}_solve_s": t_solve,
            f"{name}_relative_residual": err}


def nested_dissection_times(A: sp.csr_matrix, q: np.ndarray, free: np.ndarray, repeat: int) -> dict:
    """CHOLMOD's analysis and numeric factorisation of ``A`` in a nested-dissection order of its nodes."""
    from cvxopt import cholmod, matrix, spmatrix

    from shellform.solvers.relaxation.ordering import dof_order

    t_order, order = best(lambda: dof_order(A, q, free), 1)
    U = sp.triu(A, format="coo")
    M = spmatrix(matrix(U.data), matrix(U.row.astype(np.int64)), matrix(U.col.astype(np.int64)), A.shape)
    t_first, F = best(lambda: cholmod.symbolic(M, uplo="U", p=matrix(order.astype(np.int64))), repeat)
    t_numeric, _ = best(lambda: cholmod.numeric(M, F), repeat)
    return {"nd_order_s": t_order, "cholmod_nd_first_s": t_first + t_numeric, "cholmod_nd_refactor_s": t_numeric}


def measure(n: int, repeat: int, qdldl: bool) -> dict:
    from shellform.solvers.linear import CholeskyFactor, LDLFactor

    A, q, free = taut_tangent(n)
    b = np.random.default_rng(2).standard_normal(A.shape[0])
    row = {"nodes": n * n, "unknowns": A.shape[0], "nonzeros": int(A.nnz)}
    if qdldl:
        row.update(factor_times("qdldl", LDLFactor, {"check": None}, A, b, repeat))
    row.update(factor_times("cholmod", CholeskyFactor, {}, A, b, repeat))
    if qdldl:
        row["refactor_ratio"] = row["qdldl_refactor_s"] / row["cholmod_refactor_s"]
    row.update(nested_dissection_times(A, q, free, repeat))
    row["peak_memory_MB"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    return row


def _cell(row: dict, key: str, fmt: str) -> str:
    return format(row[key], fmt) if key in row else "-"


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="*", default=[32, 100, 316], help="nodes per side")
    ap.add_argument("--qdldl-sizes", type=int, nargs="*", default=[32, 100, 316],
                    help="the sizes on which QDLDL runs too")
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args(argv)
    rows = [measure(n, args.repeat, n in args.qdldl_sizes) for n in sorted(args.sizes)]
    for prev, r in zip(rows, rows[1:]):
        r["cholmod_refactor_growth"] = float(np.log(r["cholmod_refactor_s"] / prev["cholmod_refactor_s"])
                                             / np.log(r["unknowns"] / prev["unknowns"]))
    lines = ["| nodes | unknowns | QDLDL first [s] | QDLDL refactor [s] | CHOLMOD first [s] | CHOLMOD refactor [s] "
             "| refactor ratio | QDLDL solve [s] | CHOLMOD solve [s] | CHOLMOD refactor growth "
             "| ND order [s] | CHOLMOD ND first [s] | CHOLMOD ND refactor [s] | peak memory [MB] |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['nodes']} | {r['unknowns']} | {_cell(r, 'qdldl_first_s', '.3f')} | "
                     f"{_cell(r, 'qdldl_refactor_s', '.3f')} | {r['cholmod_first_s']:.3f} | "
                     f"{r['cholmod_refactor_s']:.3f} | {_cell(r, 'refactor_ratio', '.1f')} | "
                     f"{_cell(r, 'qdldl_solve_s', '.4f')} | {r['cholmod_solve_s']:.4f} | "
                     f"{_cell(r, 'cholmod_refactor_growth', '.2f')} | {r['nd_order_s']:.2f} | "
                     f"{r['cholmod_nd_first_s']:.3f} | {r['cholmod_nd_refactor_s']:.3f} | {r['peak_memory_MB']:.0f} |")
    load = os.getloadavg()
    lines += ["", "CHOLMOD refactor growth: exponent of the refactorisation time against the unknowns, from the "
              "size above. ND: CHOLMOD in the nested-dissection order instead of AMD.",
              "", f"Best of {args.repeat} runs; load average at the end {load[0]:.2f} (2 cores, shared). "
              f"Command: `python benchmarks/bench_factorization.py --sizes {' '.join(map(str, args.sizes))} "
              f"--qdldl-sizes {' '.join(map(str, args.qdldl_sizes))} --repeat {args.repeat}`."]
    write_results("bench_factorization", lines, rows)


if __name__ == "__main__":
    import sys

    sys.path.insert(0, str(Path(__file__).resolve().parent))
    main()
