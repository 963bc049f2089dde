"""A converged point's linearisation: the corrector's last tangent and factor against a new one at the point.

The corrector's last tangent is taken at the iterate before the last correction,
within about 1e-5 to 1e-3 of the step from the converged point. Where nothing is
counted at the point (paths traced without stability counting, such as the
hemisphere's indentation), that tangent and its factor serve as the point's
(``shellform.solvers.continuation.corrector.REUSE_DISTANCE``); off, every point is
factorised again. Each case runs in its own process, the two settings
alternating, on:

* the apex-loaded lattice domes (``bench_default_path.apex_loaded_dome``) to their
  first limit point, located, without stability counting (the limit point is
  found by the sign of dp/ds; warm, median of 5 runs);
* the hemisphere's whole mode-I indentation curve at 1 mm.

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_point_linearisation.py [--rings 10 20 30] [--sizes 5 11] [--rounds 2]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

sys.path.insert(0, os.path.dirname(__file__))


def one_case(case: str, size: int, reuse: bool) -> dict:
    import shellform.solvers.continuation.corrector as corrector
    import shellform.solvers.continuation.tracer as tracer

    if not reuse:
        corrector.REUSE_DISTANCE = -1.0
    factorisations = []
    factor = tracer.Problem.factor
    tracer.Problem.factor = lambda self, K: factorisations.append(1) or factor(self, K)
    if case == "dome":
        from bench_default_path import apex_loaded_dome

        from shellform.solvers.continuation import trace_path

        system = apex_loaded_dome(size)
        options = dict(stop_after_events=1, max_steps=200, stability=False)
        trace_path(system, "load", **options)  # warm: kernels, analyses
        walls = []
        for _ in range(5):
            factorisations.clear()
            t0 = time.perf_counter()
            res = trace_path(system, "load", **options)
            walls.append(time.perf_counter() - t0)
        ev = res.events[0]
        return {"wall": statistics.median(walls), "iterations": res.newton_iterations,
                "factorisations": len(factorisations), "result": [ev.parameter]}
    from shellform.gridshell.hemisphere import HemisphereSpec, build_hemisphere, prestress_on_net
    from shellform.gridshell.indentation import indentation_system, trace_indentation

    model = build_hemisphere(HemisphereSpec(size, voronoi_length=1e-3))
    setup = indentation_system(model, prestress_on_net(model), mode="I")
    t0 = time.perf_counter()
    res = trace_indentation(setup)
    return {"wall": time.perf_counter() - t0, "iterations": res.newton_iterations,
            "factorisations": len(factorisations), "result": list(res.thresholds) + [res.max_force]}


def run(case: str, size: int, reuse: bool) -> dict:
    out = subprocess.run([sys.executable, __file__, "--one", case, str(size), str(int(reuse))],
                         capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--rings", type=int, nargs="*", default=[10, 20, 30])
    p.add_argument("--sizes", type=int, nargs="*", default=[5, 11])
    p.add_argument("--rounds", type=int, default=2)
    p.add_argument("--one", nargs=3, help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args.one:
        print(json.dumps(one_case(args.one[0], int(args.one[1]), bool(int(args.one[2])))))
        return 0
    print(f"load average before: {open('/proc/loadavg').read().split()[:3]}")
    print("| case | size | new tangent at every point [s] | corrector's last tangent [s] | ratio | "
          "continuation factorisations (new / last) | Newton iterations (new / last) | "
          "largest relative change of the results |")
    print("|---|---:|---|---|---:|---|---|---:|")
    cases = [("dome", n) for n in args.rings] + [("hemisphere", n) for n in args.sizes]
    for case, size in cases:
        fresh, reused = [], []
        for _ in range(args.rounds):
            fresh.append(run(case, size, False))
            reused.append(run(case, size, True))
        a = statistics.median(r["wall"] for r in fresh)
        b = statistics.median(r["wall"] for r in reused)
        change = max(abs(x - y) / max(abs(x), 1e-300) for x, y in zip(fresh[0]["result"], reused[0]["result"]))
        walls_a = ", ".join(f"{r['wall']:.3f}" for r in fresh)
        walls_b = ", ".join(f"{r['wall']:.3f}" for r in reused)
        print(f"| {case} | {size} | {a:.3f} ({walls_a}) | {b:.3f} ({walls_b}) | {b / a:.2f} | "
              f"{fresh[0]['factorisations']} / {reused[0]['factorisations']} | "
              f"{fresh[0]['iterations']} / {reused[0]['iterations']} | {change:.1e} |", flush=True)
    print(f"load average after: {open('/proc/loadavg').read().split()[:3]}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
