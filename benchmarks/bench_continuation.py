"""Arc-length continuation on a ~10^4-DOF lattice dome: time per step and for a whole path.

A shallow spherical cap is covered with a triangular lattice of bars, pinned
along its rim and loaded by equal downward forces at every free node. The path
is traced under load control through its first critical points; the solver's
own timers split the time into assembly (residual and tangent), linear algebra
(factorisations and solves), stability checks (inertia beyond the
factorisation, critical modes) and event location (bisection, which contains
its own assembly and linear algebra).

    python benchmarks/bench_continuation.py [--rings 32] [--steps 40] [--solver ldl] [--compare-lu]

``--solver lu`` (SuperLU solves, separate LDL^T for the inertia) is impractical at
this size: one SuperLU factorisation of the dome's tangent takes tens of
seconds (``--compare-lu`` times one) against about 0.1 s for qdldl.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

# many tiny BLAS calls per step: threads only contend on a shared machine
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numpy as np

import shellform as sf
from shellform.solvers.continuation import trace_path
from shellform.solvers.linear import LDLFactor, LUFactor
from shellform.solvers.stability import inertia


def lattice_dome(rings: int, span: float = 10.0, rise_ratio: float = 0.08, EA: float = 1e7):
    """Triangular bar lattice on a spherical cap; ``rings`` lattice spacings from centre to rim."""
    a = 1.0
    idx = np.arange(-2 * rings - 2, 2 * rings + 3)  # wide enough to cover the whole disc
    I, J = np.meshgrid(idx, idx, indexing="ij")
    x = a * (I + 0.5 * J)
    y = a * (np.sqrt(3) / 2) * J
    keep = x**2 + y**2 <= (rings + 0.01) ** 2
    pts = np.column_stack([x[keep], y[keep]])
    index = -np.ones(I.shape, dtype=np.int64)
    index[keep] = np.arange(keep.sum())
    conn = []
    for di, dj in ((1, 0), (0, 1), (-1, 1)):
        a_idx = index[max(0, -di): index.shape[0] - max(0, di), max(0, -dj): index.shape[1] - max(0, dj)]
        b_idx = index[max(0, di):, max(0, dj):][: a_idx.shape[0], : a_idx.shape[1]]
        ok = (a_idx >= 0) & (b_idx >= 0)
        conn.append(np.column_stack([a_idx[ok], b_idx[ok]]))
    conn = np.vstack(conn)
    scale = span / (2 * rings)
    pts = pts * scale
    R_plan = span / 2
    rise = rise_ratio * span
    R_sphere = (R_plan**2 + rise**2) / (2 * rise)
    r2 = np.sum(pts**2, axis=1)
    z = np.sqrt(R_sphere**2 - r2) - (R_sphere - rise)
    s = sf.Structure(np.column_stack([pts, z]))
    s.add_bars(conn, EA)
    rim = np.flatnonzero(np.sqrt(r2) > R_plan - 1.5 * scale)  # the ragged lattice edge is held
    s.fix(rim)
    free_nodes = np.setdiff1d(np.arange(s.n_nodes), rim)
    s.add_load(free_nodes, [0.0, 0.0, -1.0])
    return sf.build_system(s)


def superlu_time(system):
    K = system.tangent_free(system.q_ref)
    t0 = time.perf_counter()
    LUFactor(K)
    return time.perf_counter() - t0


def component_times(system, repeat=3):
    """Best-of times of the pieces of one corrector iteration at the reference state."""
    q = system.q_ref.copy()
    out = {}
    t = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        system.residual(q, 1.0)
        K = system.tangent_free(q)
        t.append(time.perf_counter() - t0)
    out["assembly_s"] = min(t)
    t = []
    F = None
    for _ in range(repeat):
        t0 = time.perf_counter()
        F = LDLFactor(K, previous=F)
        t.append(time.perf_counter() - t0)
    out["ldl_refactor_s"] = min(t)
    t0 = time.perf_counter()
    inertia(K, factor=F)
    out["inertia_check_s"] = time.perf_counter() - t0
    return out


def run(rings, steps, solver):
    system = lattice_dome(rings)
    comp = component_times(system)
    n_free = system.n_free
    f = np.linalg.norm(system.load_vector())
    t0 = time.perf_counter()
    # the first critical load of this dome is a load factor of about 30 (N per node)
    def progress(pt):
        print(f"    step {pt.step:3d}  lam {pt.lam:10.5f}  negative eigenvalues {pt.n_negative:2d}  "
              f"iterations {pt.iterations}  t = {time.perf_counter() - t0:7.1f} s", file=sys.stderr, flush=True)

    res = trace_path(system, "load", initial_increment=5.0, max_steps=steps, linear_solver=solver,
                     store_states=False, callback=progress)
    wall = time.perf_counter() - t0
    t = res.timings
    step_part = t["total"] - t["event_location"]
    return {
        "solver": solver, "dof": system.n_dof, "free": n_free, "steps": res.steps, "rejected": res.rejected_steps,
        "newton": res.newton_iterations, "events": [(e.kind, round(e.parameter, 3)) for e in res.events],
        "wall_s": wall, "per_step_s": step_part / max(res.steps, 1), "timings": t, "status": res.message,
        "components": comp, "max_lam": float(res["lam"].max()), "load_norm": f,
    }


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rings", type=int, default=32)
    parser.add_argument("--steps", type=int, default=40)
    parser.add_argument("--solver", nargs="+", default=["ldl"])
    parser.add_argument("--compare-lu", action="store_true", help="also time one SuperLU factorisation")
    args = parser.parse_args()
    if args.compare_lu:
        print(f"one SuperLU factorisation of the free tangent: {superlu_time(lattice_dome(args.rings)):.2f} s",
              flush=True)
    for solver in args.solver:
        r = run(args.rings, args.steps, solver)
        t = r["timings"]
        tot = t["total"]
        other = tot - t["assembly"] - t["linear_algebra"] - t["stability"]
        print(f"linear_solver={solver}: {r['dof']} DOFs ({r['free']} free), {r['steps']} steps "
              f"({r['rejected']} rejected), {r['newton']} corrector iterations; {r['status']}")
        print(f"  whole path {tot:.2f} s, per step (excluding event location) {r['per_step_s'] * 1e3:.1f} ms; "
              f"max load factor {r['max_lam']:.1f}")
        print(f"  shares of the whole path: assembly {t['assembly'] / tot:.0%}, linear algebra "
              f"{t['linear_algebra'] / tot:.0%}, stability checks {t['stability'] / tot:.0%}, other "
              f"{other / tot:.0%}; event location (overlapping the above) {t['event_location']:.2f} s")
        print(f"  events: {r['events']}")
        c = r["components"]
        print(f"  one assembly {c['assembly_s'] * 1e3:.1f} ms, one LDL refactorisation {c['ldl_refactor_s'] * 1e3:.1f} ms, "
              f"one inertia check on that factor {c['inertia_check_s'] * 1e3:.1f} ms", flush=True)


if __name__ == "__main__":
    main()
