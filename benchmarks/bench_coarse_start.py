"""Two ways to start a net from its hanging coarse net: its shape or its force densities.

For each net, the coarse net (:func:`shellform.mra.coarsen.coarsened_net`,
every third grid line) is hung once, then the full net is relaxed to rest
with the implicit scheme from

* ``shape``: :func:`shellform.mra.start.coarse_shape_start`, the coarse
  net's positions interpolated and hung to a median rope strain of
  ``START_STRAIN`` (the default start of large nets);
* ``force_density``: :func:`shellform.mra.start.coarse_force_density_start`,
  the shape in balance with the coarse net's force densities, lowered by
  ``DENSITY_SCALE``.

The nets are the square net of ``benchmarks/bench_mra.py`` and the scenes of
``validation/mra`` (the circles at ``--n`` rope intervals per side, the large
net with frames as it is). Reported: steps and factorisations of the full
net, and the wall time of the start plus the relaxation (the coarse net's
time, shared by both, separately). Each start runs in its own process, one
after another. Writes ``benchmarks/results/bench_coarse_start.{json,md}``.

Run:  python benchmarks/bench_coarse_start.py [--n 100] [--nets square circle_sc0.02 ...]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # many small BLAS calls: threads only add overhead

import argparse  # noqa: E402
import json  # noqa: E402
import multiprocessing as mp  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
import tomllib  # noqa: E402
import warnings  # noqa: E402
from pathlib import Path  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
NETS = ["square", "circle_sc0.02", "circle_sc0.05", "circle_sc0.10", "large_frames"]


def make_net(name: str, n: int):
    """The square benchmark net of ``n + 1`` nodes per side, or a validation scene (circles at ``n``)."""
    if name == "square":
        sys.path.insert(0, str(ROOT / "benchmarks"))
        from bench_mra import make_net as square

        return square(n + 1)
    from shellform.mra.case import _merge, build_net

    params = tomllib.loads((ROOT / "validation" / "mra" / f"{name}.toml").read_text())
    if "n" in params["geometry"]:
        params["geometry"]["n"] = n
    return build_net(_merge(params))


def _run(name: str, n: int, start: str, out_q) -> None:
    from shellform.mra import form_find
    from shellform.mra.coarsen import coarsened_net
    from shellform.mra.start import coarse_force_density_start, coarse_shape_start

    warnings.simplefilter("ignore")
    net = make_net(name, n)
    t0 = time.perf_counter()
    coarse = form_find(coarsened_net(net, 3))
    t_coarse = time.perf_counter() - t0
    t1 = time.perf_counter()
    transfer = coarse_shape_start if start == "shape" else coarse_force_density_start
    q0 = transfer(coarse, net)
    res = form_find(net, q0)
    r = res.relaxation
    out_q.put({"net": name, "nodes": int(net.structure.n_nodes), "start": start, "converged": bool(r.success),
               "iterations": int(r.iterations), "factorizations": int(r.factorizations),
               "coarse_s": t_coarse, "start_and_relaxation_s": time.perf_counter() - t1,
               "rise": float(res.rise), "n_slack": int(res.slack.sum())})


def in_own_process(target, *args) -> dict:
    """``target(*args, queue)`` in a forked child (its memory and time its own); what it put on the queue."""
    ctx = mp.get_context("fork")
    q = ctx.Queue()
    p = ctx.Process(target=target, args=(*args, q))
    p.start()
    row = q.get()
    p.join()
    return row


def net_arguments(description: str) -> argparse.Namespace:
    """The command line shared by the benchmarks over these nets: ``--n``, ``--nets``, ``--out``."""
    ap = argparse.ArgumentParser(description=description)
    ap.add_argument("--n", type=int, default=100, help="rope intervals per side (square and circles)")
    ap.add_argument("--nets", nargs="*", default=NETS)
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "results"))
    return ap.parse_args()


def write_results(args, name: str, rows: list[dict], table: list[str]) -> None:
    """``<name>[_nN].json`` with the rows and ``.md`` with ``table``, the command and the load average."""
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    meta = {"command": f"python benchmarks/{name}.py " + " ".join(sys.argv[1:]),
            "load_average_at_end": os.getloadavg()}
    stem = name if args.n == 100 else f"{name}_n{args.n}"
    (out / f"{stem}.json").write_text(json.dumps({"meta": meta, "rows": rows}, indent=2) + "\n")
    lines = table + ["", f"Command: `{meta['command']}`. Load average at the end: "
                     f"{', '.join(f'{v:.2f}' for v in meta['load_average_at_end'])} (2 cores, shared)."]
    (out / f"{stem}.md").write_text("\n".join(lines) + "\n")


def main():
    args = net_arguments(__doc__.splitlines()[0])
    rows = []
    for name in args.nets:
        pair = [in_own_process(_run, name, args.n, start) for start in ("force_density", "shape")]
        pair[1]["time_ratio_to_force_density"] = (pair[1]["start_and_relaxation_s"]
                                                  / pair[0]["start_and_relaxation_s"])
        for r in pair:
            rows.append(r)
            print(f"{r['net']:>14s} {r['nodes']:>8d} {r['start']:>13s} conv={r['converged']!s:5s} "
                  f"it={r['iterations']:>4d} fact={r['factorizations']:>4d} "
                  f"t={r['start_and_relaxation_s']:8.2f} s (coarse net {r['coarse_s']:.2f} s) rise={r['rise']:.6f}",
                  flush=True)
    table = ["| net | nodes | start | converged | steps | factorisations | start + relaxation [s] | coarse net [s] |",
             "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        table.append(f"| {r['net']} | {r['nodes']} | {r['start']} | {r['converged']} | {r['iterations']} | "
                     f"{r['factorizations']} | {r['start_and_relaxation_s']:.2f} | {r['coarse_s']:.2f} |")
    write_results(args, "bench_coarse_start", rows, table)

if __name__ == "__main__":
    main()
