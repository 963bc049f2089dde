"""Past a limit point: a Cholesky factor with raised diagonal entries against LDL^T, by size.

For apex-loaded lattice domes (``bench_default_path``) of ``--rings`` rings:

* one factorisation of the free tangent at the located first limit point (one negative
  eigenvalue) with its inertia: ``RaisedCholeskyFactor`` with the row of the critical
  mode's largest entry raised, against ``LDLFactor`` (QDLDL), each reusing its analysis
  (medians of ``--repeat``), and a solve with each;
* the continuation with stability counting to the first limit point, and on for
  ``--past`` steps after it, with the raised Cholesky where a tangent has one to three
  negative eigenvalues (the default) and with LDL^T for every indefinite tangent
  (``problem.MAX_RAISED_ROWS = 0``), alternating in this process (medians of
  ``--repeat``): wall time, and whether the two paths agree (points, counts, events).

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_raised_cholesky.py [--rings 10 20 40] [--repeat 5]
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

sys.path.insert(0, os.path.dirname(__file__))

import numpy as np  # noqa: E402
from bench_default_path import apex_loaded_dome  # noqa: E402
from bench_ldl_backend import median_time  # noqa: E402

import shellform.solvers.continuation.problem as problem  # noqa: E402
from shellform.solvers.continuation import trace_path  # noqa: E402
from shellform.solvers.ldl import LDLFactor  # noqa: E402
from shellform.solvers.raised_cholesky import RaisedCholeskyFactor  # noqa: E402


def median_ms(f, repeat):
    return 1e3 * median_time(f, repeat)


def one_factorisation(system, event, repeat):
    K = system.tangent_free(event.q)
    row = int(np.argmax(np.abs(event.mode[system.free])))
    held = {"raised": [RaisedCholeskyFactor(K, [row])], "ldl": [LDLFactor(K)]}

    def raised():
        held["raised"][0] = RaisedCholeskyFactor(K, [row], previous=held["raised"][0].cholesky)

    def ldl():
        held["ldl"][0] = LDLFactor(K, previous=held["ldl"][0])

    t_raised, t_ldl = median_ms(raised, repeat), median_ms(ldl, repeat)
    b = np.random.default_rng(0).standard_normal(K.shape[0])
    s_raised = median_ms(lambda: held["raised"][0].solve(b), repeat)
    s_ldl = median_ms(lambda: held["ldl"][0].solve(b), repeat)
    counts = (held["raised"][0].n_negative_pivots, held["ldl"][0].n_negative_pivots)
    return t_raised, t_ldl, s_raised, s_ldl, counts


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--rings", type=int, nargs="+", default=[10, 20, 40])
    p.add_argument("--repeat", type=int, default=5)
    p.add_argument("--past", type=int, default=10, help="steps traced after the first limit point")
    args = p.parse_args(argv)
    print(f"load average before: {open('/proc/loadavg').read().split()[:3]}\n")
    print("| rings | free DOFs | factorisation raised / LDL^T [ms] | solve raised / LDL^T [ms] | negative eigenvalues |"
          " to the limit point: raised / LDL^T [s] | and past it: raised / LDL^T [s] | same points, counts, events |")
    print("|---:|---:|---|---|---|---|---|---|")
    default_rows = problem.MAX_RAISED_ROWS
    for rings in args.rings:
        system = apex_loaded_dome(rings)
        first = trace_path(system, "load", stop_after_events=1, max_steps=200)
        event = first.events[0]
        t_raised, t_ldl, s_raised, s_ldl, counts = one_factorisation(system, event, args.repeat)
        steps_to_past = first.steps + args.past
        walls = {("limit", "raised"): [], ("limit", "ldl"): [], ("past", "raised"): [], ("past", "ldl"): []}
        results = {}
        try:
            for _ in range(args.repeat):
                for kind, rows in (("raised", default_rows), ("ldl", 0)):
                    problem.MAX_RAISED_ROWS = rows
                    for part, options in (("limit", {"stop_after_events": 1, "max_steps": 200}),
                                          ("past", {"max_steps": steps_to_past})):
                        t0 = time.perf_counter()
                        res = trace_path(system, "load", **options)
                        walls[(part, kind)].append(time.perf_counter() - t0)
                        results[(part, kind)] = res
        finally:
            problem.MAX_RAISED_ROWS = default_rows
        same = True
        for part in ("limit", "past"):
            a, b = results[(part, "raised")], results[(part, "ldl")]
            scale = float(np.max(np.abs(b["parameter"])))
            same &= (a.n_points == b.n_points and list(a["n_negative"]) == list(b["n_negative"])
                     and float(np.max(np.abs(a["parameter"] - b["parameter"]))) <= 1e-8 * scale
                     and [e.kind for e in a.events] == [e.kind for e in b.events]
                     and all(abs(x.parameter - y.parameter) <= 2e-6 * abs(y.parameter)
                             for x, y in zip(a.events, b.events)))
        med = {k: statistics.median(v) for k, v in walls.items()}
        print(f"| {rings} | {system.n_free} | {t_raised:.1f} / {t_ldl:.1f} | {s_raised:.2f} / {s_ldl:.2f} | "
              f"{counts[0]} / {counts[1]} | {med[('limit', 'raised')]:.3f} / {med[('limit', 'ldl')]:.3f} | "
              f"{med[('past', 'raised')]:.3f} / {med[('past', 'ldl')]:.3f} | {'yes' if same else 'NO'} |", flush=True)
    print(f"\nload average after: {open('/proc/loadavg').read().split()[:3]}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
