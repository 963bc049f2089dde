"""Why the relaxation factorises: a geometric multigrid check on a rope net's tangent.

The tangent of a hanging net of nearly inextensible ropes is stiff along the
ropes (``EA / L``) and soft across them (``N / l``, smaller by the rope
strain). This script takes the tangent of the benchmark net at rest
(``bench_mra.make_net``), adds a mass term ``s`` times its mean diagonal, and
solves one system by conjugate gradients preconditioned with a geometric
V-cycle built for that anisotropy: bilinear interpolation of each displacement
component on the structured net, Galerkin coarse matrices, and alternating
line smoothers that solve each grid line's three-DOF block tridiagonal system
exactly. It then finds the tangent's lowest eigenpairs (shift-invert with its
Cholesky factor) and reports how far each mode spreads over the net.

Run:  python benchmarks/bench_net_multigrid.py [--side 200] [--out DIR]
"""

from __future__ import annotations

import argparse
import json
import os
import time
import warnings
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import scipy.sparse as sp  # noqa: E402
import scipy.sparse.linalg as spla  # noqa: E402

from bench_mra import make_net  # noqa: E402
from shellform.mra import form_find  # noqa: E402
from shellform.solvers.linear import CholeskyFactor  # noqa: E402
from shellform.solvers.relaxation.linalg import pcg  # noqa: E402

HERE = Path(__file__).resolve().parent
SHIFTS = (1.0, 1e-2, 1e-4, 1e-6)
OMEGA = 0.8  # damping of the line smoothers
MAX_CG = 500


def prolongation_1d(n: int) -> tuple[sp.csr_matrix, int]:
    """Linear interpolation from every other point (and the last) of a line of ``n`` points.

    Both end points are supports: the matrix maps the coarse interior points
    to the fine interior ones. Returns it and the number of coarse points.
    """
    coarse = np.union1d(np.arange(0, n, 2), [n - 1])
    fine = np.arange(1, n - 1)
    right = np.searchsorted(coarse, fine)  # first coarse point at or after each fine one
    on = coarse[right] == fine
    left = np.where(on, right, right - 1)
    a, b = coarse[left], coarse[right]
    w_b = np.where(on, 0.0, (fine - a) / np.maximum(b - a, 1))
    rows = np.concatenate([fine - 1, fine - 1])
    cols = np.concatenate([left, right]) - 1
    vals = np.concatenate([1.0 - w_b, w_b])
    keep = (cols >= 0) & (cols < coarse.size - 2) & (vals != 0.0)
    P = sp.csr_matrix((vals[keep], (rows[keep], cols[keep])), shape=(n - 2, coarse.size - 2))
    return P, int(coarse.size)


def line_blocks(A: sp.csr_matrix, side: int, axis: int) -> sp.csr_matrix:
    """The entries of ``A`` between nodes on the same grid line (node ``i * side + j``, 3 DOFs each)."""
    C = A.tocoo()
    a, b = C.row // 3, C.col // 3
    same = (a // side == b // side) if axis == 0 else (a % side == b % side)
    return sp.csr_matrix((C.data[same], (C.row[same], C.col[same])), shape=A.shape)


class VCycle:
    """A symmetric V-cycle for a net's tangent on ``(n - 2)^2`` interior nodes of an ``n x n`` grid."""

    def __init__(self, A: sp.csr_matrix, n: int):
        self.A = sp.csr_matrix(A)
        inner = n - 2
        if inner <= 24:
            self.exact, self.next = CholeskyFactor(self.A), None
            return
        self.exact = None
        self.along = [CholeskyFactor(line_blocks(self.A, inner, axis)) for axis in (0, 1)]
        P1, n_coarse = prolongation_1d(n)
        self.P = sp.kron(sp.kron(P1, P1), sp.eye(3)).tocsr()
        self.next = VCycle((self.P.T @ self.A @ self.P).tocsr(), n_coarse)

    def __call__(self, b: np.ndarray) -> np.ndarray:
        if self.exact is not None:
            return self.exact.solve(b)
        A, (sx, sy) = self.A, self.along
        x = OMEGA * sx.solve(b)
        x += OMEGA * sy.solve(b - A @ x)
        x += self.P @ self.next(self.P.T @ (b - A @ x))
        x += OMEGA * sy.solve(b - A @ x)
        x += OMEGA * sx.solve(b - A @ x)
        return x


def lowest_modes(K: sp.csr_matrix, count: int = 12):
    """The ``count`` lowest eigenpairs of ``K`` by shift-invert with its Cholesky factor."""
    factor = CholeskyFactor(K)
    op = spla.LinearOperator(K.shape, matvec=factor.solve, dtype=float)
    inverse, vectors = spla.eigsh(op, k=count, which="LM")
    order = np.argsort(-inverse)
    return 1.0 / inverse[order], vectors[:, order]


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--side", type=int, default=200, help="nodes per side of the benchmark net")
    ap.add_argument("--out", type=Path, default=HERE / "results", help="folder for bench_net_multigrid.{md,json}")
    args = ap.parse_args(argv)
    warnings.simplefilter("ignore")
    net = make_net(args.side)
    res = form_find(net)
    system = net.system()
    K = system.tangent_free(res.relaxation.q)
    if K.shape[0] != 3 * (args.side - 2) ** 2:
        raise SystemExit("the net's free DOFs are not its interior nodes: the grid structure is unknown")
    mean = float(K.diagonal().mean())
    b = np.random.default_rng(0).standard_normal(K.shape[0])
    rows = []
    for s in SHIFTS:
        A = (K + sp.diags(np.full(K.shape[0], s * mean))).tocsr()
        t0 = time.perf_counter()
        vcycle = VCycle(A, args.side)
        t1 = time.perf_counter()
        x, _, its = pcg(A, b, vcycle, 1e-6, MAX_CG)
        res_last = float(np.linalg.norm(b - A @ x) / np.linalg.norm(b))
        t2 = time.perf_counter()
        CholeskyFactor(A)
        t3 = time.perf_counter()
        rows.append({"mass_term": s, "cg_iterations": its, "relative_residual": res_last,
                     "setup_s": t1 - t0, "solve_s": t2 - t1, "cholmod_factorisation_s": t3 - t2})
    values, vectors = lowest_modes(K)
    energy = vectors.reshape(len(K.diagonal()) // 3, 3, -1) ** 2
    nodal = energy.sum(axis=1)
    spread = [int(np.searchsorted(np.cumsum(np.sort(col)[::-1]), 0.9) + 1) for col in nodal.T]
    vertical = energy[:, 2, :].sum(axis=0)
    modes = [{"eigenvalue_over_mean_diagonal": float(v / mean), "nodes_with_90pct": n, "vertical_share": float(z)}
             for v, n, z in zip(values, spread, vertical)]
    out = {"side": args.side, "unknowns": K.shape[0], "mean_diagonal": mean, "solves": rows, "lowest_modes": modes}
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "bench_net_multigrid.json").write_text(json.dumps(out, indent=1))
    lines = [f"Tangent of the {args.side} x {args.side} net at rest, {K.shape[0]} unknowns.", "",
             "| mass term / mean diagonal | V-cycle CG its | residual | setup [s] | solve [s] | CHOLMOD [s] |",
             "|---:|---:|---:|---:|---:|---:|"]
    lines += [f"| {r['mass_term']:g} | {r['cg_iterations']} | {r['relative_residual']:.1e} | {r['setup_s']:.2f} "
              f"| {r['solve_s']:.2f} | {r['cholmod_factorisation_s']:.2f} |" for r in rows]
    lines += ["", f"Lowest eigenvalues over the mean diagonal, and the nodes holding 90 % of each mode "
              f"(of {K.shape[0] // 3}):", "", "| eigenvalue | nodes | vertical share |", "|---:|---:|---:|"]
    lines += [f"| {m['eigenvalue_over_mean_diagonal']:.2e} | {m['nodes_with_90pct']} | {m['vertical_share']:.2f} |"
              for m in modes]
    (args.out / "bench_net_multigrid.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    return out


if __name__ == "__main__":
    main()
