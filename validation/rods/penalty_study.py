"""Joint penalty from 1e2 to 1e8 times the rods' stiffness on a buckling-induced grid.

Three rods per direction over a unit square, crossing at nine joints, start
slightly arched (2 % of the span) and have their ends pushed towards the
centre by 12.5 % of the span each (twist angles of the end edges held): the
grid rises into a dome of height ~0.28 with bending and twisting rods. The
same grid with shared joint nodes is the exact reference.

For every penalty ratio we run (a) static load stepping with Newton
(``solve_incremental``) and (b) implicit Euler with the ends moving at
constant speed, then relaxing. We report convergence, Newton iterations, the
largest joint gap and the largest distance from the shared-node solution.
Writes ``validation/rods/results/penalty_study.md`` and ``.csv``.

    python validation/rods/penalty_study.py
"""

from __future__ import annotations

import time

import numpy as np
from common import fmt, write_results

from shellform.model import Structure
from shellform.rods.grids import square_grid_polylines
from shellform.rods import RestShape, RodNetwork, RodSection, build_rod_system, stack_polylines
from shellform.rods.statics import solve_incremental
from shellform.solvers.implicit_euler import implicit_euler, lumped_mass

RATIOS = 10.0 ** np.arange(2, 9)


def arched_grid(merge: bool, ratio: float = 1e4, n: int = 3, k: int = 8, span: float = 1.0, push: float = 0.25):
    lines = square_grid_polylines(n, span, k)
    nodes, idx, pairs = stack_polylines(lines, merge=merge)
    nodes[:, 2] = 0.02 * span * np.sin(np.pi * nodes[:, 0] / span) * np.sin(np.pi * nodes[:, 1] / span)
    s = Structure(nodes)
    net = RodNetwork(s)
    for ix in idx:
        net.add_rod(ix, RodSection(EA=1e4, EI=1.0, GJ=0.75, mass_per_length=1.0, rotational_inertia=1e-4),
                    RestShape(natural_curvature="straight"))
    if not merge:
        net.add_joints(pairs, stiffness_ratio=ratio)
    for r, rod in enumerate(net.rods):
        net.fix_twist(r, "start")
        net.fix_twist(r, "end")
        a, b = rod.nodes[0], rod.nodes[-1]
        d = s.nodes[b] - s.nodes[a]
        d /= np.linalg.norm(d)
        s.prescribe([a], 0.5 * push * span * d)
        s.prescribe([b], -0.5 * push * span * d)
    return s, net, build_rod_system(net), idx, pairs


def measure(s, q, idx, pairs, ref_idx, ref):
    X = q[: 3 * s.n_nodes].reshape(-1, 3)
    gap = float(np.linalg.norm(X[pairs[:, 0]] - X[pairs[:, 1]], axis=1).max()) if len(pairs) else 0.0
    err = float(max(np.abs(X[i] - ref[j]).max() for i, j in zip(idx, ref_idx)))
    return gap, err, bool(np.all(np.isfinite(q)))


def static_run(merge, ratio=1e4):
    s, net, system, idx, pairs = arched_grid(merge, ratio)
    t0 = time.perf_counter()
    res = solve_incremental(system, mu=1.0, n_steps=10)
    return s, idx, pairs, res, time.perf_counter() - t0


def dynamic_run(merge, ratio=1e4, T=2.0, h=0.02):
    s, net, system, idx, pairs = arched_grid(merge, ratio)
    t0 = time.perf_counter()
    res = implicit_euler(system, h, 2 * T, mass=lumped_mass(s, net), damping=5.0, mu=lambda t: min(t / T, 1.0))
    return s, idx, pairs, res, time.perf_counter() - t0


def main():
    rows = []
    for kind, run in (("static", static_run), ("implicit Euler", dynamic_run)):
        s0, idx0, _, ref_res, ref_wall = run(True)
        assert ref_res.success, ref_res.message
        ref = ref_res.q[: 3 * s0.n_nodes].reshape(-1, 3)
        print(f"{kind} shared nodes: dome height {ref[:, 2].max():.4f}, wall {ref_wall:.2f} s", flush=True)
        for ratio in RATIOS:
            s, idx, pairs, res, wall = run(False, ratio)
            gap, err, finite = measure(s, res.q, idx, pairs, idx0, ref)
            its = res.iterations if kind == "static" else res.newton_iterations
            row = {
                "solver": kind, "penalty_ratio": ratio, "success": res.success, "finite": finite,
                "steps": res.n_steps if kind == "static" else res.steps,
                "rejected_steps": getattr(res, "rejected_steps", 0),
                "max_newton_per_step": max(its), "total_newton": sum(its),
                "max_joint_gap": gap, "max_distance_to_shared": err, "wall_time_s": wall,
            }
            rows.append(row)
            print(f"  ratio {ratio:7.0e}: success={res.success} finite={finite} steps={row['steps']} "
                  f"max Newton/step={row['max_newton_per_step']} total={row['total_newton']} "
                  f"gap={gap:.3e} distance={err:.3e} wall={wall:.2f}s", flush=True)
    write_results(
        "penalty_study", rows, "Joint penalty study (buckling-induced 3 x 3 grid, dome height ~0.28 span)",
        "Written by `python validation/rods/penalty_study.py`. Penalty `K_s = ratio x` the rods' "
        "axial edge stiffness `EA / L` at the joint. Distance: largest nodal distance from the "
        "solution with shared joint nodes (same solver).",
        [
            ("solver", "solver", str, False),
            ("ratio", "penalty_ratio", fmt(".0e"), True),
            ("success", "success", str, False),
            ("finite", "finite", str, False),
            ("steps", "steps", str, True),
            ("max Newton / step", "max_newton_per_step", str, True),
            ("total Newton", "total_newton", str, True),
            ("max joint gap", "max_joint_gap", fmt(".3e"), True),
            ("distance to shared", "max_distance_to_shared", fmt(".3e"), True),
            ("wall [s]", "wall_time_s", fmt(".2f"), True),
        ],
    )


if __name__ == "__main__":
    main()
