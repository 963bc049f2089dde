"""The 20-ring lattice dome to its first limit point: shellform's continuation against OpenSees's ArcLength, interleaved.

Each round runs the peer (``../shared/peers/peer_dome.py``: OpenSees ArcLength, 1 mm arc
length, SparseSYM, Newton) in its own process, then shellform's continuation with its
defaults (``bench_default_path.apex_loaded_dome``; warm, ``--repeat`` runs in this
process). Printed per round:

* OpenSees: milliseconds per Newton iteration over its 100 steps, and the time to pass
  the first limit point (the first sample past it; not located);
* shellform: the time to pass the first limit point **and** locate it to
  ``critical_rtol`` = 1e-6 (median and range), the milliseconds per corrector
  iteration on the path (the corrector's own work: residuals, tangents,
  factorisations and solves of the iterations outside the event's location), and
  the whole run divided by all its Newton iterations (the start, every point's
  tangent and stability count, the step bound and the location included).

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_dome_peer.py --peer-python /path/to/python-with-openseespy [--rounds 3]

Without ``--peer-python`` only shellform's side runs.
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

from bench_default_path import apex_loaded_dome  # noqa: E402

import shellform.solvers.continuation.tracer as tracer_module  # noqa: E402
from shellform.solvers.continuation import trace_path  # noqa: E402

PEER = os.path.join(os.path.dirname(__file__), "..", "..", "shared", "peers", "peer_dome.py")


class CorrectorClock:
    """Time and iterations of the corrector calls made by the tracer itself (steps, not event location)."""

    def __init__(self):
        self.seconds, self.iterations = 0.0, 0
        self._correct = tracer_module.correct
        tracer_module.correct = self

    def __call__(self, tr, *args):
        n0, t0 = tr.newton_total, time.perf_counter()
        try:
            return self._correct(tr, *args)
        finally:
            self.seconds += time.perf_counter() - t0
            self.iterations += tr.newton_total - n0

    def reset(self):
        self.seconds, self.iterations = 0.0, 0


def shellform_side(rings: int, repeat: int) -> dict:
    system = apex_loaded_dome(rings)
    trace_path(system, "load", stop_after_events=1, max_steps=200)  # warm: kernels, analyses
    clock = CorrectorClock()
    walls, per_iteration, whole = [], [], []
    for _ in range(repeat):
        clock.reset()
        t0 = time.perf_counter()
        res = trace_path(system, "load", stop_after_events=1, max_steps=200)
        wall = time.perf_counter() - t0
        walls.append(wall)
        per_iteration.append(clock.seconds / max(clock.iterations, 1))
        whole.append(wall / max(res.newton_iterations, 1))
    ev = res.events[0]
    return {"free_dofs": system.n_free, "limit": ev.parameter, "located": ev.located, "steps": res.steps,
            "iterations": res.newton_iterations, "path_iterations": clock.iterations, "walls": walls,
            "ms_per_path_iteration": [1e3 * x for x in per_iteration], "ms_per_iteration_whole": [1e3 * x for x in whole]}


def peer_side(python: str, rings: int) -> dict:
    env = dict(os.environ)
    lib = os.path.join(os.path.dirname(os.path.dirname(python)), "lib")
    site = [os.path.join(lib, d, "site-packages", "openseespylinux", "lib") for d in os.listdir(lib)
            if d.startswith("python")] if os.path.isdir(lib) else []
    env["LD_LIBRARY_PATH"] = ":".join(site + [env.get("LD_LIBRARY_PATH", "")])
    out = subprocess.run([python, PEER, "--n", str(rings)], capture_output=True, text=True, env=env, check=True)
    line = next(ln for ln in out.stdout.splitlines() if ln.startswith("{"))
    return json.loads(line)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--rings", type=int, default=20)
    p.add_argument("--rounds", type=int, default=3)
    p.add_argument("--repeat", type=int, default=5)
    p.add_argument("--peer-python", default=None)
    args = p.parse_args(argv)
    print(f"load average before: {open('/proc/loadavg').read().split()[:3]}")
    print("| round | OpenSees ms / Newton iteration | OpenSees to pass the limit [s] | shellform pass + locate [s] "
          "median (range) | shellform ms / corrector iteration on the path (median) | ratio to OpenSees | "
          "shellform whole run / all iterations [ms] |")
    print("|---:|---:|---:|---|---:|---:|---:|")
    for k in range(args.rounds):
        peer = peer_side(args.peer_python, args.rings) if args.peer_python else None
        ours = shellform_side(args.rings, args.repeat)
        it = statistics.median(ours["ms_per_path_iteration"])
        ratio = f"{it / peer['ms_per_newton_iter']:.2f}" if peer else "-"
        print(f"| {k + 1} | {peer['ms_per_newton_iter']:.1f} | {peer['time_to_pass_limit_s']:.2f} | "
              if peer else f"| {k + 1} | - | - | ", end="")
        print(f"{statistics.median(ours['walls']):.3f} ({min(ours['walls']):.3f}-{max(ours['walls']):.3f}) | "
              f"{it:.1f} | {ratio} | {statistics.median(ours['ms_per_iteration_whole']):.1f} |", flush=True)
    print(f"\nshellform: {ours['free_dofs']} free DOFs, {ours['steps']} steps, {ours['iterations']} Newton iterations "
          f"({ours['path_iterations']} on the path), first limit point at load factor {ours['limit']:.6g} "
          f"(located: {ours['located']})" + (f"; OpenSees: {peer['free_dofs']} free DOFs, {peer['newton_iters']} "
                                              f"iterations in {peer['steps']} steps" if peer else ""))
    print(f"load average after: {open('/proc/loadavg').read().split()[:3]}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
