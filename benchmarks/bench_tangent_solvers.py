"""The implicit relaxation's linear systems solved directly and by AMG-preconditioned CG.

Why the fast MRA scheme factorises instead of iterating: a solver whose cost
grows linearly with the net would need a preconditioner whose iteration count
does not grow. This benchmark relaxes the nets of ``bench_mra.py`` (n x n
masses, 30 m square, rim hung) with the default scheme, keeps some of the
systems ``(K + (1/h^2 + c/h) M) dq = -r`` it solves along the way (from the
softest stiffness stage to the last), and solves each one again with

* CHOLMOD (``CholeskyFactor``): analysis and factorisation, then one solve;
* conjugate gradients preconditioned by pyamg's smoothed aggregation with
  the three nodal translations as near-null space (``AMGFactor``, what
  ``factorize(A, "amg")`` builds), to a relative residual of 1e-8, at most
  ``--maxiter`` iterations.

The axial stiffness of a taut rope is its tension over its strain times the
transverse (geometric) stiffness, so the last stages' systems are the most
anisotropic. Writes ``benchmarks/results/bench_tangent_solvers.{md,json}``.

Run:  python benchmarks/bench_tangent_solvers.py [--sizes 32 100 316] [--systems 5] [--maxiter 500]
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
import scipy.sparse.linalg as spla  # noqa: E402



def captured_systems(n: int, keep_every: int = 8) -> tuple[list, int]:
    """Every ``keep_every``-th system the relaxation of an n x n net solves, and the last one.

    The relaxation's solver is wrapped for the run only (this benchmark's
    instrumentation); the relaxation itself is the default one.
    """
    from bench_mra import make_net

    from shellform.mra import form_find
    from shellform.solvers.relaxation.linalg import SPDSolve

    kept, last, count = [], [None], [0]
    original = SPDSolve.solve

    def recording(self, A, b, rtol):
        entry = (count[0], A.copy(), b.copy())
        if count[0] % keep_every == 0:
            kept.append(entry)
        last[0] = entry
        count[0] += 1
        return original(self, A, b, rtol)

    SPDSolve.solve = recording
    try:
        res = form_find(make_net(n))
    finally:
        SPDSolve.solve = original
    if not res.converged:
        raise RuntimeError(f"{n} x {n} net: {res.relaxation.message}")
    if last[0] is not None and kept[-1][0] != last[0][0]:
        kept.append(last[0])
    return kept, count[0]


def solve_both(A: sp.csr_matrix, b: np.ndarray, maxiter: int) -> dict:
    from shellform.solvers.linear import AMGFactor, CholeskyFactor

    t0 = time.perf_counter()
    x = CholeskyFactor(A).solve(b)
    t_chol = time.perf_counter() - t0
    t0 = time.perf_counter()
    amg = AMGFactor(A)
    t_setup = time.perf_counter() - t0
    its = [0]

    def count(_):
        its[0] += 1

    t0 = time.perf_counter()
    y, info = spla.cg(A, b, rtol=1e-8, maxiter=maxiter, M=amg.preconditioner, callback=count)
    t_cg = time.perf_counter() - t0
    nb = float(np.linalg.norm(b))
    return {"cholmod_s": t_chol, "cholmod_residual": float(np.linalg.norm(A @ x - b) / nb),
            "amg_setup_s": t_setup, "amg_cg_s": t_cg, "amg_iterations": its[0], "amg_converged": info == 0,
            "amg_residual": float(np.linalg.norm(A @ y - b) / nb)}


def measure(n: int, systems: int, maxiter: int) -> list[dict]:
    kept, total = captured_systems(n)
    pick = np.unique(np.linspace(0, len(kept) - 1, min(systems, len(kept))).round().astype(int))
    rows = []
    for i in pick:
        call, A, b = kept[i]
        A = sp.csr_matrix(A)
        row = {"nodes": n * n, "unknowns": A.shape[0], "system": int(call), "systems_in_run": total,
               **solve_both(A, b, maxiter)}
        row["amg_over_cholmod"] = (row["amg_setup_s"] + row["amg_cg_s"]) / row["cholmod_s"]
        rows.append(row)
        print(f"{n * n} nodes, system {call + 1} of {total}: CHOLMOD {row['cholmod_s']:.3f} s; AMG "
              f"{row['amg_iterations']} iterations, {row['amg_setup_s'] + row['amg_cg_s']:.2f} s", flush=True)
    return rows


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="*", default=[32, 100, 316], help="nodes per side")
    ap.add_argument("--systems", type=int, default=5, help="systems per size, from first to last")
    ap.add_argument("--maxiter", type=int, default=500, help="CG iterations at most")
    args = ap.parse_args(argv)
    rows = [r for n in args.sizes for r in measure(n, args.systems, args.maxiter)]
    lines = ["| nodes | unknowns | system (of run) | CHOLMOD [s] | AMG setup [s] | AMG-CG iterations | AMG-CG [s] "
             "| AMG residual | AMG / CHOLMOD time |",
             "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        its = f"{r['amg_iterations']}" + ("" if r["amg_converged"] else " (not converged)")
        lines.append(f"| {r['nodes']} | {r['unknowns']} | {r['system'] + 1} of {r['systems_in_run']} | "
                     f"{r['cholmod_s']:.3f} | {r['amg_setup_s']:.3f} | {its} | {r['amg_cg_s']:.3f} | "
                     f"{r['amg_residual']:.1e} | {r['amg_over_cholmod']:.1f} |")
    load = os.getloadavg()
    lines += ["", f"CHOLMOD: analysis, factorisation and one solve. AMG-CG to a relative residual of 1e-8, at most "
              f"{args.maxiter} iterations. Load average at the end {load[0]:.2f} (2 cores, shared). Command: "
              f"`python benchmarks/bench_tangent_solvers.py --sizes {' '.join(map(str, args.sizes))} "
              f"--systems {args.systems} --maxiter {args.maxiter}`."]
    write_results("bench_tangent_solvers", lines, rows)


if __name__ == "__main__":
    import sys

    sys.path.insert(0, str(Path(__file__).resolve().parent))
    main()
