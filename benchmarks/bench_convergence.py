"""What the equilibrium test costs: the standard solver cases, timed against another checkout.

Every case runs in a fresh process, alternating between this checkout and the one
named by ``--against`` (its ``shellform`` package comes first on ``PYTHONPATH``), so
that both see the same machine load; the table gives the medians of ``--repeat``
runs, the Newton iterations and the answer each case checks (a limit load, a
threshold, a tip position), and the ratio of the wall times.

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_convergence.py --against /path/to/other/checkout

Cases: the von Mises truss through both limit points; the 16-ring lattice dome of
``bench_continuation`` to its first critical point; a 40-edge cantilever rod under
self-weight (``EA L^2 / EI = 10^7``) in three load steps; the hemisphere's whole
mode-I indentation curve at n = 5; a 32 x 32 hanging net form-found by MRA.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

HERE = Path(__file__).resolve().parent
CASES = ("von_mises", "dome16", "cantilever", "hemisphere5", "net32")


def case_von_mises() -> dict:
    import numpy as np

    import shellform as sf
    from shellform.solvers.continuation import trace_path

    s = sf.Structure([[-1.0, 0, 0], [0.0, 0, 0.2], [1.0, 0, 0]])
    s.add_bars([[0, 1], [1, 2]], EA=1e4)
    s.fix([0, 2])
    s.fix([1], "y")
    s.add_load([1], [0, 0, -1.0])
    t0 = time.perf_counter()
    res = trace_path(sf.build_system(s), parameter_bounds=(-np.inf, 40.0), max_displacement=0.5)
    wall = time.perf_counter() - t0
    return {"wall_s": wall, "iterations": res.newton_iterations, "steps": res.steps,
            "answer": [round(e.parameter, 6) for e in res.events_of("limit")]}


def case_dome16() -> dict:
    sys.path.insert(0, str(HERE))
    from bench_continuation import lattice_dome

    from shellform.solvers.continuation import trace_path

    system = lattice_dome(16)
    t0 = time.perf_counter()
    res = trace_path(system, "load", initial_increment=0.25, max_steps=60, stop_after_events=1)
    wall = time.perf_counter() - t0
    return {"wall_s": wall, "iterations": res.newton_iterations, "steps": res.steps,
            "answer": [round(e.parameter, 6) for e in res.events]}


def case_cantilever() -> dict:
    sys.path.insert(0, str(HERE))
    from bench_rods import newton_cantilever

    out = newton_cantilever(1e7, True)
    return {"wall_s": out["wall_s"], "iterations": out["iterations"], "steps": out["steps"],
            "answer": [round(float(x), 6) for x in out["tip"]]}


def case_hemisphere5() -> dict:
    sys.path.insert(0, str(HERE))
    from bench_hemisphere import whole_curve

    out = whole_curve(5, 1e-3)
    return {"wall_s": out["trace_s"], "iterations": out["newton_iterations"], "steps": out["steps"],
            "answer": out["thresholds"] + [out["max_force"]]}


def case_net32() -> dict:
    import numpy as np

    from shellform.geometry import rectangle_grid
    from shellform.mra import hanging_net
    from shellform.mra.formfind import form_find

    # bench_mra's 32 x 32 net, built here so that any checkout can run it
    net = hanging_net(rectangle_grid(30.0, 30.0, 31, 31), {"groups": ["boundary"]}, slack=0.05, EA=1e7,
                      mass_per_length=1.0)
    t0 = time.perf_counter()
    res = form_find(net)
    wall = time.perf_counter() - t0
    return {"wall_s": wall, "iterations": int(res.relaxation.iterations), "steps": int(res.relaxation.iterations),
            "answer": [round(float(np.min(res.q[2::3])), 6)]}


def run_one(name: str) -> dict:
    return globals()[f"case_{name}"]()


def spawn(name: str, checkout: Path | None) -> dict:
    env = dict(os.environ)
    if checkout is not None:
        env["PYTHONPATH"] = str(checkout) + os.pathsep + env.get("PYTHONPATH", "")
    out = subprocess.run([sys.executable, str(Path(__file__)), "--one", name], env=env, capture_output=True,
                         text=True, check=False)
    if out.returncode != 0:
        return {"error": out.stderr.strip().splitlines()[-1] if out.stderr.strip() else f"exit {out.returncode}"}
    return json.loads(out.stdout.strip().splitlines()[-1])


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--against", type=Path, default=None, help="another checkout to compare with")
    parser.add_argument("--cases", nargs="+", default=list(CASES), choices=CASES)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--one", default=None, help=argparse.SUPPRESS)
    parser.add_argument("--json", type=Path, default=None, help="also write the results here")
    args = parser.parse_args(argv)
    if args.one:
        print(json.dumps(run_one(args.one)))
        return 0
    sides = {"this": None} if args.against is None else {"this": None, "other": args.against.resolve()}
    runs = {(c, k): [] for c in args.cases for k in sides}
    for _ in range(args.repeat):
        for c in args.cases:
            for k, path in sides.items():
                runs[(c, k)].append(spawn(c, path))
    rows = []
    print("| case | checkout | wall [s] (median) | Newton iterations | steps | answer |")
    print("|---|---|---:|---:|---:|---|")
    for c in args.cases:
        med = {}
        for k in sides:
            ok = [r for r in runs[(c, k)] if "error" not in r]
            if not ok:
                print(f"| {c} | {k} | - | - | - | {runs[(c, k)][0]['error'][:80]} |")
                continue
            med[k] = statistics.median(r["wall_s"] for r in ok)
            r0 = ok[0]
            rows.append({"case": c, "checkout": k, "wall_s": med[k], "runs": ok})
            print(f"| {c} | {k} | {med[k]:.3f} | {r0['iterations']} | {r0['steps']} | {r0['answer']} |")
        if len(med) == 2:
            print(f"| {c} | ratio this / other | {med['this'] / med['other']:.2f} | | | |")
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
