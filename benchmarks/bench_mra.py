"""MRA relaxation cost against net size.

Square nets of n x n masses on a fixed 30 m x 30 m planform, every rim node a
suspension point, slack coefficient 0.05, rope mass 1 kg/m and EA = 1e7 N (so
rope tensions and strains, about 4e-5, do not change with n). Each size is
relaxed to rest (nodal accelerations below 1e-6 g, velocities below
1e-6 sqrt(g L)) with

* the fast scheme (implicit pseudo-transient steps, default options: slack-rope
  active set, CHOLMOD supernodal Cholesky, and the default start: the coarse
  net's (below) on nets of ``COARSE_START_NODES`` nodes or more, the
  force-density shape below that);
* the same scheme started from the force-density shape on every size
  (``--force-density-sizes``), for the ratio the coarse start makes;
* the same scheme started from the shape in balance with the force densities
  of a hanging net with a third of the nodes per side, built from the
  benchmark's parameters (``--coarse-sizes``; the coarse relaxation is
  included in the wall time);
* the same scheme with ``form_find(start="coarse_net")`` (``--coarse-net-sizes``):
  the coarse net is built from the fine one (:func:`shellform.mra.coarsen.coarsened_net`,
  every third grid line, the full weight) instead of from the benchmark's
  parameters; the default start on large nets;
* the same scheme without the Newton sweeps around slack fronts
  (``--no-sweep-sizes``), for the ratio they make;
* the same scheme without the kept factor's correction on the nodes whose
  tangent entries changed (``--uncorrected-sizes``), for the ratio it makes;
* the same scheme without settling the slack set on the patches around the ropes
  whose state a step's active-set rounds leave wrong (``--unsettled-sizes``), for
  the ratio it makes;
* the same scheme cutting a step that a few ropes make overshoot, instead of
  keeping it and relaxing the patch around them (``--unrepaired-sizes``), for
  the ratio it makes;
* the same scheme without the slack-rope active set (``--plain-sizes``) and
  with QDLDL's LDL^T instead of CHOLMOD (``--ldl-sizes``), for the ratio
  each makes;
* the same scheme as it was before the force-density start (``--before-sizes``:
  flat start, LDL^T) for the before/after ratio;
* the paper's explicit RK4 scheme and kinetic damping on the smaller sizes,
  for the ratio.

Every run is a separate process, so its peak memory (``ru_maxrss``) is its
own; runs go one after another. Prints a table and writes
``benchmarks/results/bench_mra.json`` and ``.md``, with the growth of the
fast scheme's cost: exponents fitted over all sizes and over those up to
10^5 nodes, and from each size to the next, split into the growth of the
steps and of the time per step. ``--add-rows`` joins the rows of earlier
runs (for example a long 10^6-node run made on its own).

Run:  python benchmarks/bench_mra.py [--sizes 32 100 316] [--force-density-sizes 32 100 316]
      [--before-sizes 32 100] [--ldl-sizes 32 100] [--plain-sizes 32 100] [--coarse-sizes 32 100 316]
      [--no-sweep-sizes 32 100 316] [--uncorrected-sizes 32 100 316] [--unsettled-sizes 32 100 316]
      [--unrepaired-sizes 32 100 316]
      [--coarse-net-sizes 32] [--explicit-sizes 16 32] [--explicit-wall 300] [--million] [--profile DIR]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # many small BLAS calls: threads only add overhead

import argparse  # noqa: E402
import json  # noqa: E402
import multiprocessing as mp  # noqa: E402
import platform  # noqa: E402
import resource  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from shellform.solvers.relaxation import Refinements  # noqa: E402

SIDE = 30.0
EA = 1.0e7
SLACK = 0.05
#: the fit "to 1e5" is over the sizes up to this many nodes (the standard 10^3, 10^4, 10^5)
SMALL_FIT_NODES = 120_000

# the variants of a run: form_find's keywords
VARIANTS = {
    "fast": {"scheme": "implicit"},
    "force_density": {"scheme": "implicit", "start": "force_density"},
    "ldl": {"scheme": "implicit", "linear_solver": "ldl"},
    "plain": {"scheme": "implicit", "refinements": Refinements(slack_active_set=False)},
    "no_sweeps": {"scheme": "implicit", "refinements": Refinements(front_sweeps=False)},
    "uncorrected": {"scheme": "implicit", "refinements": Refinements(factor_correction=False)},
    "unsettled": {"scheme": "implicit", "refinements": Refinements(slack_settling=False)},
    "unrepaired": {"scheme": "implicit", "refinements": Refinements(step_repair=False)},
    "before": {"scheme": "implicit", "start": "reference", "linear_solver": "ldl"},
    "coarse": {"scheme": "implicit"},  # started from a coarser net's force densities (see _coarse_start)
    "coarse_net": {"scheme": "implicit", "start": "coarse_net"},  # form_find's own coarse net, from the net itself
    "kinetic": {"scheme": "kinetic"},
    "rk4": {"scheme": "rk4"},
}


def make_net(n_nodes_side: int):
    from shellform.geometry import rectangle_grid
    from shellform.mra import hanging_net

    grid = rectangle_grid(SIDE, SIDE, n_nodes_side - 1, n_nodes_side - 1)
    return hanging_net(grid, {"groups": ["boundary"]}, slack=SLACK, EA=EA, mass_per_length=1.0)


def _progress(n, variant):
    """A callback printing one line per implicit step (or per 2000 explicit steps) to stderr."""
    def cb(info):
        print(f"    [{n * n} {variant}] it {info.iteration} t {info.wall_time_s:.1f} s "
              f"max a {info.max_acceleration:.2e} |r| {info.residual_norm:.2e}", file=os.sys.stderr, flush=True)
    return cb


def _run(n: int, variant: str, wall: float | None, out_q, verbose=False, profile=None):
    """One relaxation in this (child) process; puts a row and the positions on ``out_q``.

    With ``profile`` (a directory), the form finding runs under ``cProfile`` and
    its statistics go to ``profile_<nodes>_<variant>.prof`` there.
    """
    from shellform.mra import form_find

    t0 = time.perf_counter()
    net = make_net(n)
    build = time.perf_counter() - t0
    c0 = time.process_time()
    cb = _progress(n, variant) if verbose else None
    t1 = time.perf_counter()
    q0 = _coarse_start(net, n) if variant == "coarse" else None
    prep = time.perf_counter() - t1
    if profile:
        import cProfile

        profiler = cProfile.Profile()
        res = profiler.runcall(form_find, net, q0, max_wall_time=wall, callback=cb, **VARIANTS[variant])
        profiler.dump_stats(str(Path(profile) / f"profile_{n * n}_{variant}.prof"))
    else:
        res = form_find(net, q0, max_wall_time=wall, callback=cb, **VARIANTS[variant])
    r = res.relaxation
    row = {
        "nodes": n * n, "variant": variant, "scheme": r.scheme, "start": r.start, "converged": bool(r.success),
        "iterations": int(r.iterations), "factorizations": int(r.factorizations),
        "cg_iterations": int(r.linear_iterations), "local_steps": int(r.local_steps),
        "repaired_steps": int(r.repaired_steps),
        "corrected_solves": int(r.corrected_solves), "residual_evaluations": int(r.residual_evaluations),
        "rejected_steps": int(r.rejected_steps), "wall_time_s": float(r.wall_time_s) + prep, "preparation_s": prep,
        "cpu_time_s": time.process_time() - c0, "build_s": build,
        "peak_memory_MB": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
        "max_velocity": float(r.max_velocity), "max_acceleration": float(r.max_acceleration),
        "acceleration_tol": float(r.acceleration_tol), "residual_norm": float(r.residual_norm),
        "n_slack": int(res.slack.sum()), "rise": float(res.rise), "message": r.message,
    }
    out_q.put((row, res.positions))


def _coarse_start(net, n: int):
    """The shape in balance with the force densities of a net with a third of the nodes per side."""
    from shellform.mra import form_find
    from shellform.mra.start import coarse_force_density_start

    return coarse_force_density_start(form_find(make_net(max(round((n - 1) / 3), 2) + 1)), net)


def run(n: int, variant: str, wall: float | None = None, verbose: bool = False, profile: str | None = None):
    ctx = mp.get_context("fork")  # the parent has not imported shellform: each child starts clean
    q = ctx.Queue()
    p = ctx.Process(target=_run, args=(n, variant, wall, q, verbose, profile))
    p.start()
    row, pos = q.get()
    p.join()
    return row, pos


def growth(rows, key):
    x = np.log([r["nodes"] for r in rows])
    return float(np.polyfit(x, np.log([r[key] for r in rows]), 1)[0])


def growth_between(rows) -> list[dict]:
    """Exponents of wall time, steps and wall time per step from each size of ``rows`` to the next.

    Wall time = steps x time per step, so the two exponents add up to the
    first: they tell whether a steeper decade comes from more steps or from
    dearer ones (the factorisation's fill grows faster than the nodes).
    """
    out = []
    for a, b in zip(rows, rows[1:]):
        span = np.log(b["nodes"] / a["nodes"])
        per_step = [r["wall_time_s"] / max(r["iterations"], 1) for r in (a, b)]
        out.append({"from_nodes": a["nodes"], "to_nodes": b["nodes"],
                    "wall_time_s": float(np.log(b["wall_time_s"] / a["wall_time_s"]) / span),
                    "iterations": float(np.log(b["iterations"] / a["iterations"]) / span),
                    "wall_time_per_iteration": float(np.log(per_step[1] / per_step[0]) / span)})
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--sizes", type=int, nargs="*", default=[32, 100, 316])
    ap.add_argument("--before-sizes", type=int, nargs="*", default=[32, 100])
    ap.add_argument("--ldl-sizes", type=int, nargs="*", default=[32, 100])
    ap.add_argument("--plain-sizes", type=int, nargs="*", default=[32, 100])
    ap.add_argument("--no-sweep-sizes", type=int, nargs="*", default=[32, 100])
    ap.add_argument("--uncorrected-sizes", type=int, nargs="*", default=[32, 100])
    ap.add_argument("--unsettled-sizes", type=int, nargs="*", default=[32, 100])
    ap.add_argument("--unrepaired-sizes", type=int, nargs="*", default=[32, 100])
    ap.add_argument("--force-density-sizes", type=int, nargs="*", default=[32, 100, 316])
    ap.add_argument("--coarse-sizes", type=int, nargs="*", default=[32, 100, 316])
    ap.add_argument("--coarse-net-sizes", type=int, nargs="*", default=[32])
    ap.add_argument("--explicit-sizes", type=int, nargs="*", default=[16, 32])
    ap.add_argument("--explicit-wall", type=float, default=300.0)
    ap.add_argument("--million", action="store_true", help="also try 1000 x 1000 nodes")
    ap.add_argument("--skip-fast", action="store_true",
                    help="run only the chosen variants at --sizes (one long run of a variant, joined later with --add-rows)")
    ap.add_argument("--wall", type=float, default=None, help="wall-time limit of each implicit run [s]")
    ap.add_argument("--verbose", action="store_true", help="print every implicit step to stderr")
    ap.add_argument("--profile", default=None,
                    help="a directory: run the fast scheme's relaxations under cProfile and write their statistics "
                         "there (their times then include the profiler's overhead)")
    ap.add_argument("--add-rows", nargs="*", default=[],
                    help="a bench_mra.json of an earlier run whose rows join this one's (e.g. a long 10^5 run)")
    ap.add_argument("--out", default=str(Path(__file__).resolve().parent / "results"))
    args = ap.parse_args()
    sizes = sorted(set(args.sizes) | ({1000} if args.million else set()))
    rows = []

    def report(row):
        rows.append(row)
        print(f"{row['nodes']:>8d} {row['variant']:>8s} {row['start']:>13s} conv={row['converged']!s:5s} "
              f"it={row['iterations']:>7d} fact={row['factorizations']:>4d} cg={row['cg_iterations']:>6d} "
              f"local={row.get('local_steps', 0):>4d} corr={row.get('corrected_solves', 0):>4d} "
              f"rep={row.get('repaired_steps', 0):>3d} "
              f"t={row['wall_time_s']:9.2f} s cpu={row['cpu_time_s']:9.2f} s mem={row['peak_memory_MB']:7.0f} MB "
              f"a={row['max_acceleration']:.1e}  slack={row['n_slack']}", flush=True)

    fast = {}
    for n in sizes:
        row, pos = (None, None) if args.skip_fast else run(n, "fast", args.wall, args.verbose, args.profile)
        if row is not None:
            fast[n] = (row, pos)
            report(row)
        for variant, chosen in (("force_density", args.force_density_sizes), ("coarse", args.coarse_sizes),
                                ("coarse_net", args.coarse_net_sizes), ("no_sweeps", args.no_sweep_sizes),
                                ("uncorrected", args.uncorrected_sizes), ("unsettled", args.unsettled_sizes),
                                ("unrepaired", args.unrepaired_sizes),
                                ("plain", args.plain_sizes), ("ldl", args.ldl_sizes), ("before", args.before_sizes)):
            if n in chosen:
                row_b, pos_b = run(n, variant, args.wall, args.verbose)
                if row is not None:
                    row_b["shape_difference"] = float(np.abs(pos_b - pos).max())
                    row_b["time_ratio_to_fast"] = row_b["wall_time_s"] / row["wall_time_s"]
                report(row_b)
    for n in sorted(set(args.explicit_sizes)):
        if n not in fast:
            fast[n] = run(n, "fast")
            fast[n][0]["explicit_reference_only"] = True  # not one of the sizes of the growth fit
            report(fast[n][0])
        ref_row, ref_pos = fast[n]
        for variant in ("kinetic", "rk4"):
            row, pos = run(n, variant, args.explicit_wall)
            row["shape_difference"] = float(np.abs(pos - ref_pos).max())
            row["time_ratio_to_fast"] = row["wall_time_s"] / ref_row["wall_time_s"]
            report(row)
    fit_nodes = {n * n for n in sizes}
    joined = []
    measured = bool(rows)
    for path in args.add_rows:
        data = json.loads(Path(path).read_text())
        added = data["rows"]
        joined.append(data.get("meta", {}))
        rows.extend(added)
        # the sizes of the fit are those of the fast rows; an explicit run's size is a reference only
        fit_nodes |= {r["nodes"] for r in added if r["variant"] == "fast" and not r.get("explicit_reference_only")}
    fit = sorted((r for r in rows if r["variant"] == "fast" and r["converged"] and r["nodes"] in fit_nodes),
                 key=lambda r: r["nodes"])
    exps, between = None, []
    if len(fit) >= 2:
        exps = {k + "_exponent": growth(fit, k) for k in ("wall_time_s", "cpu_time_s", "iterations",
                                                           "factorizations", "peak_memory_MB")}
        if len(fit) >= 3:
            exps["wall_time_s_exponent_last_two"] = growth(fit[-2:], "wall_time_s")
        small = [r for r in fit if r["nodes"] <= SMALL_FIT_NODES]
        if 2 <= len(small) < len(fit):
            exps["wall_time_s_exponent_to_1e5"] = growth(small, "wall_time_s")
        print("growth with the number of nodes: " + ", ".join(f"{k} {v:.2f}" for k, v in exps.items()))
        between = growth_between(fit)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    # a run that only joins earlier rows reports the load of the run that measured them
    load = os.getloadavg() if measured or not joined else joined[0].get("load_average_at_end", os.getloadavg())
    meta = {"machine": platform.processor() or platform.machine(), "python": platform.python_version(),
            "load_average_at_end": load, "side_m": SIDE, "EA_N": EA, "slack": SLACK,
            "command": "python benchmarks/bench_mra.py " + " ".join(os.sys.argv[1:])}
    if joined:
        meta["joined_from"] = joined
    (out / "bench_mra.json").write_text(json.dumps({"meta": meta, "rows": rows, "growth": exps,
                                                   "growth_between": between}, indent=2, default=float) + "\n")
    lines = ["| nodes | variant | start | converged | iterations | factorizations | CG its | corrected solves "
             "| local steps | repaired steps | wall [s] | CPU [s] | peak memory [MB] | max a [m/s^2] |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['nodes']} | {r['variant']} ({r['scheme']}) | {r['start']} | {r['converged']} | "
                     f"{r['iterations']} | {r['factorizations']} | {r['cg_iterations']} | "
                     f"{r.get('corrected_solves', '-')} | {r.get('local_steps', 0)} | {r.get('repaired_steps', '-')} | "
                     f"{r['wall_time_s']:.2f} | "
                     f"{r['cpu_time_s']:.2f} | {r['peak_memory_MB']:.0f} | {r['max_acceleration']:.1e} |")
    if exps:
        lines += ["", "Growth exponents (fast scheme, fitted over the converged sizes): "
                  + ", ".join(f"{k} {v:.2f}" for k, v in exps.items())]
    if between:
        lines += ["", "Growth from each size to the next (fast scheme; the exponents of the steps and of the "
                  "time per step add up to that of the wall time):", "",
                  "| nodes | wall time | steps | wall time per step |", "|---|---|---|---|"]
        lines += [f"| {g['from_nodes']} to {g['to_nodes']} | N^{g['wall_time_s']:.2f} | N^{g['iterations']:.2f} | "
                  f"N^{g['wall_time_per_iteration']:.2f} |" for g in between]
    lines += ["", f"Load average at the end: {', '.join(f'{v:.2f}' for v in load)} (2 cores, shared)."]
    (out / "bench_mra.md").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
