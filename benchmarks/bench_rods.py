"""Assembly of a rod network (stretch + bend + twist + joints) against one sparse solve of its tangent.

A square grid of rods crossing at penalty joints is bent into a dome-like
shape with twisted edges (so every term of the bending and twisting
derivatives is active, including the transport from the stored frames). We
time each effect's gradient and Hessian values, the full residual + free
tangent assembly, and one factorisation + solve of that tangent, best of
several repeats, all in one run.

    python benchmarks/bench_rods.py [--rods 14 30] [--edges-per-cell 6] [--repeat 5]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from shellform.model import Structure
from shellform.rods.grids import square_grid_polylines
from shellform.rods.network import RodNetwork, build_rod_system, circular_section, stack_polylines
from shellform.solvers.linear import SingularMatrixError, factorize


def dome_network(n: int, edges_per_cell: int, span: float = 0.12):
    lines = square_grid_polylines(n, span, edges_per_cell)
    nodes, idx, pairs = stack_polylines(lines)
    s = Structure(nodes)
    net = RodNetwork(s)
    sec = circular_section(E=1e11, G=1e11 / 3, radius=1e-3, density=1e3)
    for ix in idx:
        net.add_rod(ix, **sec, natural_curvature="straight")
    net.add_joints(pairs, stiffness_ratio=1e4)
    for r in range(len(idx)):
        net.pin(r, "start", twist="fixed")
        net.pin(r, "end", twist="fixed")
    system = build_rod_system(net)
    rng = np.random.default_rng(0)
    q = s.reference_state()
    X = q[: 3 * s.n_nodes].reshape(-1, 3)
    X[:, 2] = 0.3 * span * np.sin(np.pi * X[:, 0] / span) * np.sin(np.pi * X[:, 1] / span)
    q[3 * s.n_nodes :] = 0.1 * rng.normal(size=s.n_twist)
    # move the stored frames half way, so the transport terms are exercised
    net.frames.update(0.5 * (q + s.reference_state()))
    return system, q


def best_of(fn, repeat):
    times, out = [], None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return min(times), out


def run(n, edges_per_cell, repeat):
    system, q = dome_network(n, edges_per_cell)
    row = {"rods": 2 * n, "dof": system.n_dof, "free": system.n_free}
    for e in system.effects:
        if e.name in ("rod_stretch", "rod_bend", "rod_twist", "joints"):
            row[e.name] = best_of(lambda: (e.gradient(q), e.hessian_values(q)), repeat)[0]
    row["assembly"], K = best_of(lambda: (system.residual(q), system.tangent_free(q))[1], repeat)
    row["nnz"] = K.nnz
    rhs = -system.residual(q)[system.free]
    for method in ("direct", "ldl"):
        try:
            row[method] = best_of(lambda: factorize(K, method).solve(rhs), max(1, repeat // 2))[0]
        except (SingularMatrixError, ValueError) as exc:  # pragma: no cover - reported, not hidden
            row[method] = float("nan")
            print(f"  {method}: {exc}")
    return row


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rods", type=int, nargs="+", default=[14, 30], help="rods per direction")
    parser.add_argument("--edges-per-cell", type=int, default=6)
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    head = ["rods", "dof", "free", "nnz", "rod_stretch", "rod_bend", "rod_twist", "joints", "assembly", "direct", "ldl"]
    print(" ".join(f"{h:>11}" for h in head) + "   (times in s: gradient + Hessian values per effect;"
          " assembly = residual + free tangent; solve = factorise + solve)")
    for n in args.rods:
        r = run(n, args.edges_per_cell, args.repeat)
        print(" ".join(f"{r[h]:11d}" if isinstance(r[h], (int, np.integer)) else f"{r[h]:11.4f}" for h in head),
              flush=True)


if __name__ == "__main__":
    main()
