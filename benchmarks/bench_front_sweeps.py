"""What the Newton sweeps around slack fronts save, with and without the slack-rope active set.

Each net is relaxed to rest by ``form_find`` with its default start, four
times: with the slack-rope active set and the front sweeps (the default),
with the active set alone, with the sweeps alone (``form_find`` leaves them
out without the active set, so this run forces them on through the module's
internals, to show why) and with neither. Reported: steps and factorisations of the
whole net, patch steps, the wall time of the relaxation and the part of it
spent in the sweeps. The nets are those of ``bench_coarse_start.py``: the
square net of ``bench_mra.py`` and the scenes of ``validation/mra``. Each
run is its own process, one after another. Writes
``benchmarks/results/bench_front_sweeps[_nN].{json,md}``.

Run:  python benchmarks/bench_front_sweeps.py [--n 100] [--nets square circle_sc0.02 ...]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # many small BLAS calls: threads only add overhead

import sys  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402
from pathlib import Path  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_coarse_start import in_own_process, make_net, net_arguments, write_results  # noqa: E402

#: (slack active set, front sweeps)
VARIANTS = [(True, True), (True, False), (False, True), (False, False)]


def _run(name: str, n: int, active: bool, sweeps: bool, out_q) -> None:
    from shellform.mra import form_find
    from shellform.solvers.relaxation import Refinements, implicit
    from shellform.solvers.relaxation.patch import NodeGraph, patchable

    warnings.simplefilter("ignore")
    spent = [0.0]
    sweep = implicit.sweep_fronts

    def timed(*args):
        t = time.perf_counter()
        out = sweep(*args)
        spent[0] += time.perf_counter() - t
        return out

    implicit.sweep_fronts = timed
    if sweeps and not active:
        # form_find leaves the sweeps out without the active set; put them in to measure why
        stage_of = implicit._stage
        graphs = {}

        def forced(system, *args):
            # one graph per net (a coarse net first, on large nets): the stages' stiffer copies share its structure
            stage = stage_of(system, *args)
            key = id(system.structure)
            if key not in graphs:
                graphs[key] = NodeGraph(system) if patchable(system) else None
            stage.graph = graphs[key]
            return stage

        implicit._stage = forced
    net = make_net(name, n)
    res = form_find(net, refinements=Refinements(slack_active_set=active, front_sweeps=sweeps))
    r = res.relaxation
    out_q.put({"net": name, "nodes": int(net.structure.n_nodes), "active_set": active, "front_sweeps": sweeps,
               "converged": bool(r.success), "iterations": int(r.iterations),
               "factorizations": int(r.factorizations), "local_steps": int(r.local_steps),
               "wall_time_s": float(r.wall_time_s), "sweep_s": spent[0], "rise": float(res.rise),
               "max_acceleration": float(r.max_acceleration)})


def main():
    args = net_arguments(__doc__.splitlines()[0])
    rows = []
    for name in args.nets:
        for active, sweeps in VARIANTS:
            r = in_own_process(_run, name, args.n, active, sweeps)
            rows.append(r)
            print(f"{r['net']:>14s} {r['nodes']:>8d} active={active!s:5s} sweeps={sweeps!s:5s} "
                  f"conv={r['converged']!s:5s} it={r['iterations']:>4d} fact={r['factorizations']:>4d} "
                  f"local={r['local_steps']:>4d} t={r['wall_time_s']:8.2f} s (sweeps {r['sweep_s']:.2f} s)",
                  flush=True)
    table = ["| net | nodes | active set | front sweeps | converged | steps | factorisations | patch steps "
             "| relaxation [s] | of it in sweeps [s] |", "|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        table.append(f"| {r['net']} | {r['nodes']} | {r['active_set']} | {r['front_sweeps']} | {r['converged']} | "
                     f"{r['iterations']} | {r['factorizations']} | {r['local_steps']} | {r['wall_time_s']:.2f} | "
                     f"{r['sweep_s']:.2f} |")
    write_results(args, "bench_front_sweeps", rows, table)

if __name__ == "__main__":
    main()
