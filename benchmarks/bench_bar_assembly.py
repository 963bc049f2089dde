"""Bars' tangent and forces compiled or by NumPy, by size: where the compiled kernels pay for their loading.

For apex-loaded lattice domes (``bench_default_path``) of ``--rings`` rings, in this
process: the median time of one free tangent and of one residual with the bars'
NumPy law (the full 6 x 6 blocks summed by one ``bincount``, and the upper triangles
summed by the System's constant 0/1 matrix) and with the compiled kernels
(upper triangles added into the tangent's data; ``AxialBar.compiled_from`` set to put
every size on either side), and the assemblies (one tangent and two residuals, about what a Newton
iteration takes) after which the saving has paid the kernels' load in a fresh process
(measured in a subprocess that has imported shellform: numba's import and the cached
kernels' first calls).

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_bar_assembly.py [--rings 3 5 10 15 20 40] [--repeat 30]
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

sys.path.insert(0, os.path.dirname(__file__))

from bench_default_path import apex_loaded_dome  # noqa: E402
from bench_ldl_backend import median_time  # noqa: E402

from shellform.effects.axial import AxialBar  # noqa: E402

LOAD = """
import time
import numpy as np
import shellform
t0 = time.perf_counter()
from shellform.effects import rod_compiled as c
q = np.zeros(6); dofs = np.arange(6, dtype=np.int64).reshape(1, 6); q[3] = 1.0
c.stretch_energies(q, dofs, np.ones(1), np.ones(1), np.zeros(6))
data = np.zeros(22); slots = np.zeros((1, 21), dtype=np.int32)
c.add_stretch_values(q, dofs, np.ones(1), np.ones(1), data, slots, slots)
print(time.perf_counter() - t0)
"""


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--rings", type=int, nargs="+", default=[3, 5, 10, 15, 20, 40])
    p.add_argument("--repeat", type=int, default=30)
    args = p.parse_args(argv)
    loads = [float(subprocess.run([sys.executable, "-c", LOAD], capture_output=True, text=True, check=True).stdout)
             for _ in range(3)]
    load = statistics.median(loads)
    print(f"kernels' load in a fresh process: {load:.3f} s (median of {', '.join(f'{x:.3f}' for x in loads)})\n")
    print("| rings | bars | tangent NumPy, full blocks [ms] | tangent NumPy, upper triangles [ms] | "
          "tangent compiled [ms] | residual NumPy [ms] | residual compiled [ms] | assemblies to pay the load |")
    print("|---:|---:|---:|---:|---:|---:|---:|---:|")
    default = AxialBar.compiled_from
    upper_pattern = AxialBar.hessian_upper_pattern
    try:
        for rings in args.rings:
            row = {}
            for name, threshold in (("full", 10**12), ("numpy", 10**12), ("compiled", 0)):
                AxialBar.compiled_from = threshold
                if name == "full":
                    AxialBar.hessian_upper_pattern = lambda self: None
                try:
                    system = apex_loaded_dome(rings)
                finally:
                    AxialBar.hessian_upper_pattern = upper_pattern
                q = system.q_ref.copy()
                system.tangent_free(q), system.residual(q)
                row[name] = (median_time(lambda: system.tangent_free(q), args.repeat),
                             median_time(lambda: system.residual(q), args.repeat))
            bars = sum(len(e.L) for e in system.effects if isinstance(e, AxialBar))
            saved = (row["numpy"][0] - row["compiled"][0]) + 2 * (row["numpy"][1] - row["compiled"][1])
            pays = f"{load / saved:.0f}" if saved > 0 else "never"
            print(f"| {rings} | {bars} | {row['full'][0] * 1e3:.3f} | {row['numpy'][0] * 1e3:.3f} | "
                  f"{row['compiled'][0] * 1e3:.3f} | "
                  f"{row['numpy'][1] * 1e3:.3f} | {row['compiled'][1] * 1e3:.3f} | {pays} |", flush=True)
    finally:
        AxialBar.compiled_from = default
    print(f"\nAxialBar.compiled_from = {default}")


if __name__ == "__main__":
    main()
