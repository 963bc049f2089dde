"""Dense symmetric eigenvalues of small matrices with the BLAS threads the process has, and on one.

The stability check of a small model (under 400 free DOFs) may compute all
eigenvalues of its tangent densely. Each run is a fresh process with
``OPENBLAS_NUM_THREADS`` set to ``--threads``; it times ``scipy.linalg.eigvalsh``
of random symmetric matrices as they are and inside
:func:`shellform.solvers.linear.single_threaded` (median and largest of
``--repeat`` calls), and the cost of entering that block.

    python benchmarks/bench_dense_threads.py [--sizes 100 250 400] [--threads 2] [--repeat 30]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time


def measure(n: int, repeat: int) -> dict:
    import numpy as np
    import scipy.linalg as sla

    from shellform.solvers.linear import single_threaded

    rng = np.random.default_rng(0)
    A = rng.standard_normal((n, n))
    A = A + A.T

    def timed(fn):
        ts = []
        for _ in range(repeat):
            t0 = time.perf_counter()
            fn()
            ts.append(time.perf_counter() - t0)
        return float(np.median(ts)), float(max(ts))

    def limited():
        with single_threaded():
            sla.eigvalsh(A)

    def enter():
        with single_threaded():
            pass

    plain = timed(lambda: sla.eigvalsh(A))
    one = timed(limited)
    return {"n": n, "plain_median_s": plain[0], "plain_max_s": plain[1], "one_thread_median_s": one[0],
            "one_thread_max_s": one[1], "enter_s": timed(enter)[0]}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--sizes", type=int, nargs="+", default=[100, 250, 400])
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--repeat", type=int, default=30)
    p.add_argument("--one", type=int, default=None, help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args.one is not None:
        print(json.dumps(measure(args.one, args.repeat)))
        return 0
    print(f"| n | {args.threads} threads: median [ms] | largest [ms] | one thread: median [ms] | largest [ms] | "
          "entering the block [ms] |")
    print("|---:|---:|---:|---:|---:|---:|")
    env = dict(os.environ, OPENBLAS_NUM_THREADS=str(args.threads), OMP_NUM_THREADS=str(args.threads))
    for n in args.sizes:
        out = subprocess.run([sys.executable, __file__, "--one", str(n), "--repeat", str(args.repeat)], env=env,
                             capture_output=True, text=True, check=True)
        r = json.loads(out.stdout.splitlines()[-1])
        print(f"| {n} | {1e3 * r['plain_median_s']:.2f} | {1e3 * r['plain_max_s']:.1f} | "
              f"{1e3 * r['one_thread_median_s']:.2f} | {1e3 * r['one_thread_max_s']:.1f} | {1e3 * r['enter_s']:.3f} |",
              flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
