"""Continuum limit of the MRA net: a square net with equal force densities under a
uniform load approaches the small-slope membrane as the grid is refined.

Three solutions of the same problem (side a = 1 m, load p = 1 N/m^2, membrane
force N = q = 1 N/m):

1. the MRA relaxation (implicit scheme) of nets of n x n cells whose ropes all
   have the force density q and whose nodes are masses of weight p h^2;
2. the same nets as a linear force-density problem solved with pyamg;
3. the continuum membrane N laplacian(w) = -p by scikit-fem (quadratic
   triangles, pyamg-preconditioned CG), checked against the analytic
   coefficient (shellform.validation.reference.MEMBRANE_SQUARE_COEFFICIENT).

The same for unstructured nets of the square meshed by gmsh at edge lengths
1/8 .. 1/64: triangles with the cotangent force densities that make the net
the linear finite elements of the membrane (second order), triangles with
equal force densities (a different surface: about the membrane of force
sqrt(3) q), and the quads gmsh makes of a square (a regular grid) with equal
ones; the deflection at the centre interpolated linearly over the faces.

Writes ``results/continuum_limit.png`` (centre-deflection error against the
grid spacing) and ``results/continuum_limit.json``.

Run:  python validation/mra/continuum_limit.py
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # tiny BLAS calls: threads only add overhead

import json  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import matplotlib  # noqa: E402

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from shellform.assembly import build_system  # noqa: E402
from shellform.geometry.planforms import polygon_planform  # noqa: E402
from shellform.mra.membrane import (deflection_at, force_density_net, force_density_solve,  # noqa: E402
                                    membrane_centre_deflection, membrane_force_densities,
                                    unstructured_force_density_net)
from shellform.solvers.relaxation import RelaxationOptions, relax  # noqa: E402
from shellform.io.files import write_text  # noqa: E402
from shellform.validation.reference import MEMBRANE_SQUARE_COEFFICIENT  # noqa: E402
from shellform.io.table import save_figure  # noqa: E402

HERE = Path(__file__).resolve().parent


#: nets of the square meshed by gmsh: how their force densities are set
UNSTRUCTURED = {"triangles, cotangent force densities": ("triangles", "cotangent"),
                "triangles, equal force densities": ("triangles", "equal"),
                "quads (gmsh), equal force densities": ("quads", "equal")}


def unstructured_row(h: float, elements: str, densities: str, w_fem: float) -> dict:
    """The MRA relaxation of a gmsh net of the unit square at edge length ``h``, its centre deflection and error."""
    g = polygon_planform([(0, 0), (1, 0), (1, 1), (0, 1)], edge_length=h, elements=elements)
    faces = g.triangles if elements == "triangles" else g.quads
    if elements == "triangles":
        edges, q, area = membrane_force_densities(g.nodes, g.triangles)
    else:
        edges = g.edges
        p = g.nodes[g.quads]
        quad_area = 0.5 * np.linalg.norm(np.cross(p[:, 2] - p[:, 0], p[:, 3] - p[:, 1]), axis=1)
        area = np.bincount(g.quads.ravel(), weights=np.repeat(quad_area / 4, 4), minlength=g.n_nodes)
        q = np.ones(len(edges))
    if densities == "equal":
        q = np.ones(len(edges))
    res = relax(build_system(unstructured_force_density_net(g.nodes, edges, q, area, g.boundary)),
                options=RelaxationOptions(scheme="implicit", rtol=1e-10), start="reference")
    w = deflection_at(g.nodes, faces, -res.q.reshape(-1, 3)[:, 2], (0.5, 0.5))
    return {"h": h, "nodes": int(g.n_nodes), "converged": bool(res.success), "iterations": int(res.iterations),
            "wall_time_s": float(res.wall_time_s), "w_centre": float(w),
            "error_vs_continuum": float(abs(w - w_fem) / w_fem), "continuum_over_net": float(w_fem / w)}


def main(sizes=(4, 8, 16, 32, 64, 128)) -> dict:
    out = HERE / "results"
    out.mkdir(exist_ok=True)
    coeff = MEMBRANE_SQUARE_COEFFICIENT
    t0 = time.perf_counter()
    w_fem = membrane_centre_deflection(refine=7)
    fem_time = time.perf_counter() - t0
    rows = []
    for n in sizes:
        s, grid, centre = force_density_net(n)
        system = build_system(s)
        # from the flat reference state: the force-density start would already be the
        # answer of the linear comparison below
        res = relax(system, options=RelaxationOptions(scheme="implicit", rtol=1e-10), start="reference")
        w_mra = -res.q[3 * centre + 2]
        w_fd = force_density_solve(n)[n // 2 - 1, n // 2 - 1]
        rows.append({
            "n": n, "h": 1.0 / n, "converged": bool(res.success), "iterations": int(res.iterations),
            "wall_time_s": float(res.wall_time_s), "w_mra": float(w_mra), "w_force_density": float(w_fd),
            "mra_vs_force_density": float(abs(w_mra - w_fd) / w_fd),
            "error_vs_continuum": float(abs(w_mra - w_fem) / w_fem),
        })
        print(f"n = {n:4d}: MRA {w_mra:.8f} ({res.iterations} it., {res.wall_time_s:.2f} s), "
              f"force density {w_fd:.8f}, error vs continuum {rows[-1]['error_vs_continuum']:.3e}")
    h = np.array([r["h"] for r in rows])
    err = np.array([r["error_vs_continuum"] for r in rows])
    order = np.polyfit(np.log(h), np.log(err), 1)[0]
    summary = {
        "continuum_fem": w_fem, "continuum_fem_time_s": fem_time, "analytic_coefficient": coeff,
        "fem_vs_analytic": abs(w_fem - coeff) / coeff, "observed_order": float(order), "nets": rows,
    }
    summary["unstructured"] = {}
    for name, (elements, densities) in UNSTRUCTURED.items():
        net_rows = [unstructured_row(1.0 / m, elements, densities, w_fem) for m in (8, 16, 32, 64)]
        e = np.array([r["error_vs_continuum"] for r in net_rows])
        hh = np.array([r["h"] for r in net_rows])
        summary["unstructured"][name] = {"nets": net_rows, "observed_order": float(np.polyfit(np.log(hh), np.log(e), 1)[0])}
        print(f"{name}: errors " + ", ".join(f"{v:.2e}" for v in e)
              + f"; continuum / net {net_rows[-1]['continuum_over_net']:.4f} at h = 1/64")
    write_text(out / "continuum_limit.json", json.dumps(summary, indent=2) + "\n")

    fig, ax = plt.subplots(figsize=(5.5, 4.0))
    ax.loglog(h, err, "o-", label="structured grid, equal force densities (MRA)")
    ax.loglog(h, [abs(r["w_force_density"] - w_fem) / w_fem for r in rows], "x", ms=9,
              label="linear force density (pyamg)")
    for (name, u), marker in zip(summary["unstructured"].items(), "s^v"):
        ax.loglog([r["h"] for r in u["nets"]], [r["error_vs_continuum"] for r in u["nets"]], marker + "-", ms=5,
                  label=f"{name} (order {u['observed_order']:.2f})")
    ax.loglog(h, err[0] * (h / h[0]) ** 2, "k--", lw=0.8, label="slope 2")
    ax.set_xlabel("grid spacing h / a")
    ax.set_ylabel("relative error of the centre deflection")
    ax.set_title(f"Nets of a square -> membrane\n(structured grid, equal force densities: order {order:.2f})")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7, loc="lower right")
    fig.tight_layout()
    save_figure(fig, out / "continuum_limit.png", dpi=150)
    print(f"continuum (scikit-fem P2): {w_fem:.8f}; analytic coefficient {coeff}; observed order {order:.2f}")
    return summary


if __name__ == "__main__":
    sizes = tuple(int(a) for a in sys.argv[1:]) or (4, 8, 16, 32, 64, 128)
    main(sizes)
