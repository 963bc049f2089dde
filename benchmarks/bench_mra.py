"""MRA relaxation cost against net size.

Square nets of n x n masses on a fixed 30 m x 30 m planform, every rim node a
suspension point, slack coefficient 0.05, rope mass 1 kg/m and EA = 1e7 N (so
rope tensions and strains, about 4e-5, do not change with n). Each size is
relaxed to rest (nodal accelerations below 1e-6 g, velocities below
1e-6 sqrt(g L)) with

* the fast scheme (implicit pseudo-transient steps) from the flat planform;
* the same from a B-spline start fitted to a 4x coarser net (the coarse solve
  is included in the time);
* the paper's explicit RK4 scheme and kinetic damping on the smaller sizes,
  for the ratio.

Prints a table and writes ``benchmarks/results/bench_mra.json`` and ``.md``.

Run:  python benchmarks/bench_mra.py [--sizes 32 100 316] [--explicit-sizes 16 32]
      [--explicit-wall 900] [--million]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # many small BLAS calls: threads only add overhead

import argparse  # noqa: E402
import json  # noqa: E402
import platform  # noqa: E402
import resource  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from shellform.geometry import rectangle_grid  # noqa: E402
from shellform.mra import fit_height_field, form_find, hanging_net, surface_start  # noqa: E402

SIDE = 30.0
EA = 1.0e7
SLACK = 0.05


def make_net(n_nodes_side: int):
    t0 = time.perf_counter()
    grid = rectangle_grid(SIDE, SIDE, n_nodes_side - 1, n_nodes_side - 1)
    net = hanging_net(grid, {"groups": ["boundary"]}, slack=SLACK, EA=EA, mass_per_length=1.0)
    return net, time.perf_counter() - t0


def run(net, scheme, q0=None, **kw):
    res = form_find(net, q0, scheme=scheme, **kw)
    r = res.relaxation
    return {
        "scheme": scheme, "converged": bool(r.success), "iterations": int(r.iterations),
        "factorizations": int(r.factorizations), "cg_iterations": int(r.linear_iterations),
        "residual_evaluations": int(r.residual_evaluations), "wall_time_s": float(r.wall_time_s),
        "max_velocity": float(r.max_velocity), "max_acceleration": float(r.max_acceleration),
        "acceleration_tol": float(r.acceleration_tol), "n_slack": int(res.slack.sum()),
        "rise": float(res.rise), "message": r.message, "positions": res.positions,
    }


def coarse_start(n_side: int, factor: int = 4):
    """B-spline start from a net with (n_side - 1) / factor cells per side; returns (q0, seconds, iterations)."""
    t0 = time.perf_counter()
    nc = (n_side - 1) // factor
    cnet = hanging_net(rectangle_grid(SIDE, SIDE, nc, nc), {"groups": ["boundary"]}, slack=SLACK, EA=EA,
                       mass_per_length=1.0)
    c = form_find(cnet)
    hf = fit_height_field(c.positions, (0, SIDE), (0, SIDE), n_ctrl=max(4, min(12, nc // 2)))
    return hf, time.perf_counter() - t0, int(c.relaxation.iterations)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--sizes", type=int, nargs="*", default=[32, 100, 316])
    ap.add_argument("--explicit-sizes", type=int, nargs="*", default=[16, 32])
    ap.add_argument("--explicit-wall", type=float, default=900.0)
    ap.add_argument("--million", action="store_true", help="also try 1000 x 1000 nodes")
    args = ap.parse_args()
    sizes = list(args.sizes) + ([1000] if args.million else [])
    rows = []

    def report(row):
        rows.append({k: v for k, v in row.items() if k != "positions"})
        print(f"{row['nodes']:>8d} {row['scheme']:>9s} {row['start']:>7s} conv={row['converged']!s:5s} "
              f"it={row['iterations']:>7d} fact={row['factorizations']:>4d} cg={row['cg_iterations']:>6d} "
              f"t={row['wall_time_s']:9.2f} s  a={row['max_acceleration']:.1e}  slack={row['n_slack']}", flush=True)

    for n in sorted(set(args.explicit_sizes)):
        net, _ = make_net(n)
        ref = run(net, "implicit")
        ref.update(nodes=n * n, start="flat")
        report(ref)
        for scheme in ("kinetic", "rk4"):
            row = run(net, scheme, max_wall_time=args.explicit_wall)
            row.update(nodes=n * n, start="flat",
                       shape_difference=float(np.abs(row["positions"] - ref["positions"]).max()),
                       time_ratio=row["wall_time_s"] / ref["wall_time_s"])
            report(row)
    for n in sizes:
        net, build = make_net(n)
        row = run(net, "implicit")
        row.update(nodes=n * n, start="flat", build_s=build,
                   peak_memory_MB=resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024)
        report(row)
        if n >= 64:
            hf, prep, cit = coarse_start(n)
            q0 = surface_start(net, hf)
            row2 = run(net, "implicit", q0)
            row2.update(nodes=n * n, start="coarse", preparation_s=prep, coarse_iterations=cit,
                        shape_difference=float(np.abs(row2["positions"] - row["positions"]).max()))
            row2["wall_time_s"] += prep
            report(row2)
    flat = [r for r in rows if r["scheme"] == "implicit" and r["start"] == "flat" and r["nodes"] in
            [s * s for s in sizes]]
    growth = None
    if len(flat) >= 2:
        x = np.log([r["nodes"] for r in flat])
        growth = {
            "wall_time_exponent": float(np.polyfit(x, np.log([r["wall_time_s"] for r in flat]), 1)[0]),
            "iterations_exponent": float(np.polyfit(x, np.log([r["iterations"] for r in flat]), 1)[0]),
        }
        print(f"growth with the number of nodes: wall time ~ N^{growth['wall_time_exponent']:.2f}, "
              f"iterations ~ N^{growth['iterations_exponent']:.2f}")
    out = Path(__file__).resolve().parent / "results"
    out.mkdir(exist_ok=True)
    meta = {"machine": platform.processor() or platform.machine(), "python": platform.python_version(),
            "load_average": os.getloadavg(), "side_m": SIDE, "EA_N": EA, "slack": SLACK}
    (out / "bench_mra.json").write_text(json.dumps({"meta": meta, "rows": rows, "growth": growth}, indent=2,
                                                   default=float) + "\n")
    lines = ["| nodes | scheme | start | converged | iterations | factorizations | CG its | wall [s] | max a [m/s^2] |",
             "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['nodes']} | {r['scheme']} | {r['start']} | {r['converged']} | {r['iterations']} | "
                     f"{r['factorizations']} | {r['cg_iterations']} | {r['wall_time_s']:.2f} | "
                     f"{r['max_acceleration']:.1e} |")
    (out / "bench_mra.md").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
