"""How many Lanczos vectors the eigenvalue nearest zero needs: solves and time by basis size, across models.

The eigenvalue of a tangent nearest zero (a bifurcation's test function, the critical
mode of a located event, the stability monitor) is found by shift-invert Lanczos about
zero with the factor of the tangent itself, one solve per Lanczos vector. ARPACK's
default basis (``ncv`` = 20 for one eigenvalue) costs 20 solves before it first tests
convergence. For each model and basis size: the solves, the time, and the eigenvalue's
and the unit eigenvector's difference from the default basis's; "short first" is
``shellform.solvers.stability.eigsh_nearest_zero`` (a short basis with few restarts,
then the default).

Models: apex-loaded lattice domes (``bench_default_path``) at their located first limit
point; the pre-stressed hemisphere's free indentation tangent (mode I, 1 mm), whose soft
rod modes cluster near zero; the same tangent shifted to put zero among them.

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_lanczos_basis.py [--rings 10 20 40] [--sizes 5 11]
"""

from __future__ import annotations

import argparse
import os
import sys
import time

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numpy as np
import scipy.sparse.linalg as spla

sys.path.insert(0, os.path.dirname(__file__))

from shellform.solvers.factor_base import shift_diagonal  # noqa: E402
from shellform.solvers.ldl import LDLFactor  # noqa: E402
from shellform.solvers.stability import eigsh_nearest_zero, start_vector  # noqa: E402

BASES = (None, 4, 6, 8, 12, "short first")


def rows(name, K, tol):
    n = K.shape[0]
    F = LDLFactor(K)
    solves = [0]

    def apply(b):
        solves[0] += 1
        return F.solve(np.ravel(b))

    op = spla.LinearOperator((n, n), matvec=apply, dtype=float)
    ref = None
    for ncv in BASES:
        solves[0] = 0
        t0 = time.perf_counter()
        try:
            if ncv == "short first":
                w, V = eigsh_nearest_zero(K, apply, tol=tol, vectors=True)
            else:
                w, V = spla.eigsh(K, k=1, sigma=0.0, which="LM", OPinv=op, v0=start_vector(n), tol=tol,
                                  **({} if ncv is None else {"ncv": ncv}))
        except spla.ArpackNoConvergence:
            print(f"| {name} | {n} | {tol:g} | {ncv or 'default (20)'} | no convergence | | | |")
            continue
        dt = time.perf_counter() - t0
        v = V[:, 0] * np.sign(V[np.argmax(np.abs(V[:, 0])), 0])
        if ref is None:
            ref = (float(w[0]), v)
        dlam = abs(float(w[0]) - ref[0]) / max(abs(ref[0]), 1e-300)
        print(f"| {name} | {n} | {tol:g} | {ncv or 'default (20)'} | {solves[0]} | {dt * 1e3:.1f} | {dlam:.1e} | "
              f"{np.linalg.norm(v - ref[1]):.1e} |", flush=True)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--rings", type=int, nargs="*", default=[10, 20, 40])
    p.add_argument("--sizes", type=int, nargs="*", default=[5, 11])
    args = p.parse_args(argv)
    print("| model | unknowns | tol | Lanczos vectors | solves | time [ms] | eigenvalue vs default (rel.) | "
          "eigenvector vs default |")
    print("|---|---:|---:|---|---:|---:|---:|---:|")
    from bench_default_path import tangent_past_first_limit

    for rings in args.rings:
        K = tangent_past_first_limit(rings)
        for tol in (0.0, 1e-6):
            rows(f"dome {rings} rings, at its limit point", K, tol)
    for n in args.sizes:
        from shellform.gridshell.hemisphere import HemisphereSpec, build_hemisphere, prestress_on_net
        from shellform.gridshell.indentation import indentation_system
        from shellform.solvers.stability import smallest_eigenpair

        model = build_hemisphere(HemisphereSpec(n, voronoi_length=1e-3))
        pre = prestress_on_net(model)
        K = indentation_system(model, pre, mode="I").system.tangent_free(pre.q).tocsr()
        for tol in (0.0, 1e-6):
            rows(f"hemisphere n = {n}, pre-stressed", K, tol)
        lam, _ = smallest_eigenpair(K)
        Ks = shift_diagonal(K, -3.5 * abs(lam))
        for tol in (0.0, 1e-6):
            rows(f"hemisphere n = {n}, shifted among its soft modes", Ks, tol)


if __name__ == "__main__":
    main()
