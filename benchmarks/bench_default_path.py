"""Continuation with its defaults alone: lattice domes of 10^2 to 3 x 10^4 DOFs to their first critical point.

No step size, no parameter bound and no tolerance is given: the first step comes from
the linearised distance to the nearest critical point, the convergence test from the
forces in play (``shellform/solvers/step_bounds.py``, ``shellform/solvers/equilibrium.py``).
Each dome is the triangular bar lattice of ``bench_continuation`` on a 50 m cap of 5 m
rise (steel bars, EA = 420 MN), pinned along its rim, under a 1 kN apex load.

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_default_path.py [--rings 2 5 10 20 40 60]
"""

from __future__ import annotations

import argparse
import os
import sys
import time

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numpy as np

from bench_continuation import lattice_dome
from shellform.solvers.continuation import trace_path


def apex_loaded_dome(rings: int):
    system = lattice_dome(rings, span=50.0, rise_ratio=0.1, EA=210e9 * 2e-3)
    s = system.structure
    apex = int(np.argmin(np.linalg.norm(s.nodes[:, :2], axis=1)))
    s.load_cases.clear()
    s.add_load([apex], [0.0, 0.0, -1000.0])
    import shellform as sf

    return sf.build_system(s)


def tangent_past_first_limit(rings: int):
    """The free tangent of the apex-loaded dome at its located first limit point (one negative eigenvalue)."""
    system = apex_loaded_dome(rings)
    event = trace_path(system, "load", stop_after_events=1, max_steps=200).events[0]
    return system.tangent_free(event.q)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rings", type=int, nargs="+", default=[2, 5, 10, 20, 40, 60])
    args = parser.parse_args(argv)
    print("| rings | free DOFs | steps | Newton iterations | first event | load factor | wall [s] | event location [s] | message |")
    print("|---:|---:|---:|---:|---|---:|---:|---:|---|")
    for n in args.rings:
        system = apex_loaded_dome(n)
        t0 = time.perf_counter()
        res = trace_path(system, "load", stop_after_events=1, max_steps=200)
        wall = time.perf_counter() - t0
        ev = res.events[0] if res.events else None
        print(f"| {n} | {system.n_free} | {res.steps} | {res.newton_iterations} | {ev.kind if ev else '-'} | "
              f"{ev.parameter if ev else float('nan'):.6g} | {wall:.1f} | {res.timings.get('event_location', 0.0):.1f} | "
              f"{res.message[:60]} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
