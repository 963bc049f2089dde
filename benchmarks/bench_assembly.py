"""Assembly (residual + free tangent) against one sparse solve of that tangent, and the set-up of a System.

A square rope net hangs from its edges in a sagged, fully taut state; we time
the assembly of residual and CSR tangent and one linear solve of the tangent
with each solver, best of several repeats, all in the same run.

    python benchmarks/bench_assembly.py [--members 10000 100000] [--repeat 5]

``--setup N ...`` times ``build_system`` instead on square nets of N x N nodes
(the effects' own pattern and the System's CSR patterns, best of ``--repeat``);
with ``--against OTHER_CHECKOUT`` each size alternates between this checkout and
the other, one fresh process per run, and the ratio is printed:

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_assembly.py --setup 100 316 --against /path/to/other --repeat 5
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time

import numpy as np

import shellform as sf
from shellform.solvers.linear import SingularMatrixError, factorize


def sagged_net(target_members: int):
    n = max(2, int(round((-1 + np.sqrt(1 + 2 * target_members)) / 2)))  # 2 n (n + 1) edges
    xs = np.linspace(0.0, 1.0, n + 1)
    X, Y = np.meshgrid(xs, xs, indexing="ij")
    nodes = np.column_stack([X.ravel(), Y.ravel(), np.zeros(X.size)])
    idx = np.arange(X.size).reshape(n + 1, n + 1)
    conn = np.vstack([
        np.column_stack([idx[:-1, :].ravel(), idx[1:, :].ravel()]),
        np.column_stack([idx[:, :-1].ravel(), idx[:, 1:].ravel()]),
    ])
    s = sf.Structure(nodes)
    s.add_ropes(conn, EA=1e5, slack=0.0, mass_per_length=1.0)
    s.fix(np.unique(np.concatenate([idx[0], idx[-1], idx[:, 0], idx[:, -1]])))
    s.set_gravity()
    system = sf.build_system(s)
    q = s.reference_state().reshape(-1, 3)
    q[:, 2] = -0.2 * np.sin(np.pi * X.ravel()) * np.sin(np.pi * Y.ravel())  # sagged: every rope taut
    return system, q.ravel()


def best_of(fn, repeat):
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return min(times), out


def run(members, repeat):
    system, q = sagged_net(members)
    n_m = sum(g.n_members for g in system.structure.groups)
    t_asm, K = best_of(lambda: (system.residual(q), system.tangent_free(q))[1], repeat)
    rhs = -system.residual(q)[system.free]
    t_ldl, _ = best_of(lambda: factorize(K, "ldl").solve(rhs), max(1, repeat // 2))
    t_lu = float("nan")
    if K.shape[0] < 50_000:  # SuperLU takes minutes above this size
        t_lu, _ = best_of(lambda: factorize(K, "lu").solve(rhs), 1)
    try:
        t_amg, _ = best_of(lambda: factorize(K, "amg").solve(rhs), 1)
    except SingularMatrixError:
        t_amg = float("nan")  # CG did not reach its tolerance in its iteration budget
    return {
        "members": n_m, "free_dof": system.n_free, "nnz": K.nnz,
        "assembly_s": t_asm, "ldl_solve_s": t_ldl, "lu_solve_s": t_lu, "amg_cg_solve_s": t_amg,
        "ldl/assembly": t_ldl / t_asm,
    }


def square_net(n: int) -> sf.Structure:
    """n x n nodes on a unit square, ropes along the grid lines, the rim held, self-weight."""
    xs = np.linspace(0.0, 1.0, n)
    X, Y = np.meshgrid(xs, xs, indexing="ij")
    nodes = np.column_stack([X.ravel(), Y.ravel(), np.zeros(X.size)])
    idx = np.arange(X.size).reshape(n, n)
    conn = np.vstack([np.column_stack([idx[:-1, :].ravel(), idx[1:, :].ravel()]),
                      np.column_stack([idx[:, :-1].ravel(), idx[:, 1:].ravel()])])
    s = sf.Structure(nodes)
    s.add_ropes(conn, EA=1e5, slack=0.0, mass_per_length=1.0)
    s.fix(np.unique(np.concatenate([idx[0], idx[-1], idx[:, 0], idx[:, -1]])))
    s.set_gravity()
    return s


def setup_time(n: int, repeat: int) -> dict:
    """Best wall time of ``build_system`` on the n x n net, and of its System part alone."""
    from shellform.assembly import System, member_effects

    s = square_net(n)
    t_build, system = best_of(lambda: sf.build_system(s), repeat)
    effects = list(system.effects)
    t_system, _ = best_of(lambda: System(s, effects), repeat)
    t_effects, _ = best_of(lambda: member_effects(s), repeat)
    return {"nodes": n * n, "build_system_s": t_build, "system_s": t_system, "member_effects_s": t_effects}


def setup_against(sizes, other: str, repeat: int) -> None:
    """``build_system`` here and in ``other``, alternating fresh processes; medians and ratios."""
    import statistics

    here = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    print("| nodes | build_system here [s] | System here [s] | build_system other [s] | System other [s] | other / here |")
    print("|---:|---:|---:|---:|---:|---:|")
    for n in sizes:
        runs = {here: [], other: []}
        for _ in range(repeat):
            for root in (other, here):
                env = dict(os.environ, PYTHONPATH=root)
                out = subprocess.run([sys.executable, os.path.abspath(__file__), "--setup", str(n), "--repeat", "1",
                                      "--json"], env=env, capture_output=True, text=True, check=True, cwd="/")
                runs[root].append(json.loads(out.stdout.splitlines()[-1]))
        med = {r: {k: statistics.median(x[k] for x in v) for k in ("build_system_s", "system_s")} for r, v in runs.items()}
        print(f"| {n * n:,} | {med[here]['build_system_s']:.3f} | {med[here]['system_s']:.3f} | "
              f"{med[other]['build_system_s']:.3f} | {med[other]['system_s']:.3f} | "
              f"{med[other]['build_system_s'] / med[here]['build_system_s']:.2f} |", flush=True)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--members", type=int, nargs="+", default=[10_000, 100_000])
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--setup", type=int, nargs="+", default=None, help="time build_system on N x N nets")
    parser.add_argument("--against", default=None, help="another checkout to time --setup against")
    parser.add_argument("--json", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.setup:
        if args.against:
            setup_against(args.setup, args.against, args.repeat)
            return
        for n in args.setup:
            r = setup_time(n, args.repeat)
            print(json.dumps(r) if args.json else
                  f"{r['nodes']:9d} nodes: build_system {r['build_system_s']:.3f} s, System {r['system_s']:.3f} s, "
                  f"member effects {r['member_effects_s']:.3f} s", flush=True)
        return
    print(f"{'members':>8} {'free DOF':>9} {'nnz':>9} {'assembly s':>11} {'LDL solve s':>12} "
          f"{'LU solve s':>11} {'AMG-CG s':>9} {'LDL/assembly':>13}")
    for m in args.members:
        r = run(m, args.repeat)
        print(f"{r['members']:8d} {r['free_dof']:9d} {r['nnz']:9d} {r['assembly_s']:11.4f} {r['ldl_solve_s']:12.4f} "
              f"{r['lu_solve_s']:11.4f} {r['amg_cg_solve_s']:9.4f} {r['ldl/assembly']:13.1f}", flush=True)


if __name__ == "__main__":
    main()
