"""Rod networks: assembly against one sparse solve, and static Newton iterations against axial stiffness.

``assembly``: a square grid of rods crossing at penalty joints is bent into a
dome-like shape with twisted edges (so every term of the bending and twisting
derivatives is active, including the transport from the stored frames). We
time each effect's gradient and Hessian values, the full residual + free
tangent assembly, and one factorisation + solve of that tangent, best of
several repeats, all in one run.

``tangent``: the pre-stressed hemispherical gridshell of the indentation
benchmark (``--hemisphere-n`` rods per direction, apex prescribed, state
perturbed so that every term is active): each effect's Hessian values as the
tangent takes them (the upper triangles of the element blocks where the
effect gives them; the stretching added straight into the tangent's data
where the System does so), the bending and twisting together in one pass
(``hinges``, as the tangent evaluates them: added straight into the
tangent's data by the compiled kernel where numba is installed), the free
tangent as the
continuation assembles it (``System.tangent_free``), and
a numeric refactorisation of that tangent with the symbolic analysis kept
(CHOLMOD Cholesky and QDLDL LDL^T, each reusing its previous factor), best of
``--repeat``; the ratio tangent / Cholesky refactorisation is the figure of
merit, best against best (each repeated alone, its data warm) and as the
median ratio of tangents and refactorisations taken alternately, as in a
Newton loop (``interleaved``).

``newton``: static Newton (``solve_incremental``) with and without the stretch
projection of the line search (:class:`shellform.solvers.newton.StretchProjection`),
in the same run: the self-weight cantilever (alpha = 39.24, 40 edges, 3 load
steps, halved when a step fails) for several ``EA L^2 / EI``, and the
hemispherical gridshell raised by its rod ends along their paths (the
paper's route, ``--hemisphere-n`` rods per direction, 40 steps). Reported:
load steps taken, Newton iterations (total and largest per step), wall time.

    python benchmarks/bench_rods.py [--part assembly tangent newton] [--rods 14 30] [--edges-per-cell 6] [--repeat 5]
                                    [--axial-ratios 1e3 1e5 1e7 1e9] [--hemisphere-n 5]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from shellform.model import Structure
from shellform.rods.grids import square_grid_polylines
from shellform.rods import RestShape, RodNetwork, build_rod_system, circular_section, stack_polylines
from shellform.rods.statics import solve_incremental
from shellform.solvers.linear import SingularMatrixError, factorize
from shellform.validation.cases_rods import G, clamped_stations, straight_rod


def dome_network(n: int, edges_per_cell: int, span: float = 0.12):
    lines = square_grid_polylines(n, span, edges_per_cell)
    nodes, idx, pairs = stack_polylines(lines)
    s = Structure(nodes)
    net = RodNetwork(s)
    sec = circular_section(E=1e11, G=1e11 / 3, radius=1e-3, density=1e3)
    for ix in idx:
        net.add_rod(ix, sec, RestShape(natural_curvature="straight"))
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


def tangent_values(e, q):
    """An effect's Hessian values as the free tangent takes them: upper triangles where the effect gives them."""
    upper = getattr(e, "hessian_upper_pattern", lambda: None)()  # (checkouts before the upper triangles have none)
    return e.hessian_values(q) if upper is None else e.hessian_upper_values(q)


def summed_hinge_values(system, q):
    """The bending and twisting Hessian values of the rod hinges, summed in one pass as the tangent takes them."""
    from shellform.effects.rod_hinge import HingeEffect

    hinges = [e for e in system.effects if isinstance(e, HingeEffect)]
    if not hasattr(HingeEffect, "summed_hessian_upper_values"):  # checkouts before: each effect in turn
        return lambda: [e.hessian_values(q) for e in hinges]
    return lambda: type(hinges[0]).summed_hessian_upper_values(hinges, q)


def direct_values(system, q, effect):
    """Adding the values of the group of ``effect`` straight into the free tangent's data, where the System does
    so (compiled kernels), else None."""
    upper = getattr(system, "_upper_free", None)
    direct = getattr(upper, "direct", {})
    summed = getattr(system, "_upper", None)  # an UpperTangent, or (groups, ...) in checkouts before
    groups = [] if summed is None else summed.groups if hasattr(summed, "groups") else summed[0]
    for g, (_, ks, _) in enumerate(groups):
        if g in direct and any(system.effects[k] is effect for k in ks):
            data = np.zeros(upper.size)
            effects = [system.effects[k] for k in ks]
            return lambda: direct[g](effects, q, data)
    return None


def tangent_hinge_values(system, q):
    """The bending and twisting values as the free tangent takes them: added straight into its data where the
    System does so, else summed in one pass."""
    from shellform.effects.rod_hinge import HingeEffect

    hinge = next(e for e in system.effects if isinstance(e, HingeEffect))
    return direct_values(system, q, hinge) or summed_hinge_values(system, q)


def run(n, edges_per_cell, repeat):
    system, q = dome_network(n, edges_per_cell)
    row = {"rods": 2 * n, "dof": system.n_dof, "free": system.n_free}
    for e in system.effects:
        if e.name in ("rod_stretch", "rod_bend", "rod_twist", "joints"):
            row[e.name] = best_of(lambda: (e.gradient(q), tangent_values(e, q)), repeat)[0]
    row["hinges"] = best_of(summed_hinge_values(system, q), repeat)[0]
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


def hemisphere_tangent(n: int, repeat: int) -> dict:
    from shellform.gridshell.hemisphere import HemisphereSpec, build_hemisphere, prestress_on_net
    from shellform.gridshell.indentation import indentation_system
    from shellform.solvers.cholesky import CholeskyFactor
    from shellform.solvers.ldl import LDLFactor

    model = build_hemisphere(HemisphereSpec(n))
    pre = prestress_on_net(model)
    setup = indentation_system(model, pre, mode="I")
    system = setup.system
    rng = np.random.default_rng(1)
    q = system.state(mu=1e-3 * model.radius)
    q[system.free] += 1e-4 * model.radius * rng.normal(size=system.n_free)
    row = {"n": n, "free": system.n_free}
    for e in system.effects:
        if e.name in ("rod_bend", "rod_twist", "joints"):
            row[e.name] = best_of(lambda: tangent_values(e, q), repeat)[0]
        elif e.name == "rod_stretch":
            row[e.name] = best_of(direct_values(system, q, e) or (lambda: tangent_values(e, q)), repeat)[0]
    row["hinges"] = best_of(tangent_hinge_values(system, q), repeat)[0]
    row["tangent"], K = best_of(lambda: system.tangent_free(q), repeat)
    row["nnz"] = K.nnz
    # numeric refactorisations: the symbolic analysis of the previous factor is kept
    for name, cls in (("cholesky", CholeskyFactor), ("ldl", LDLFactor)):
        try:
            F = [cls(K)]

            def refactor():
                F[0] = cls(K, previous=F[0])

            row[name] = best_of(refactor, repeat)[0]
        except Exception as exc:  # pragma: no cover - reported, not hidden
            row[name] = float("nan")
            print(f"  {name}: {exc}")
    row["ratio"] = row["tangent"] / row["cholesky"]
    # as in a Newton loop: each tangent after a refactorisation, whose memory traffic leaves the tangent's data cold
    F = [CholeskyFactor(K)]
    ratios = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        system.tangent_free(q)
        t1 = time.perf_counter()
        F[0] = CholeskyFactor(K, previous=F[0])
        ratios.append((t1 - t0) / (time.perf_counter() - t1))
    row["interleaved"] = float(np.median(ratios))
    return row


def newton_cantilever(axial_ratio: float, project: bool) -> dict:
    s, net = straight_rod(clamped_stations(40), EA=axial_ratio, EI=1.0, mass_per_length=39.24 / G)
    net.clamp(0, "start")
    s.set_gravity((0.0, 0.0, -G))
    system = build_rod_system(net, gravity_scaled=True)
    t0 = time.perf_counter()
    res = solve_incremental(system, lam=1.0, n_steps=3, project=project)
    tip = res.q[3 * (s.n_nodes - 1): 3 * s.n_nodes]
    return {"case": f"cantilever EA L^2/EI = {axial_ratio:.0e}", "success": res.success, "steps": res.n_steps,
            "iterations": sum(res.iterations), "max_per_step": max(res.iterations, default=0),
            "wall_s": time.perf_counter() - t0, "tip": (tip[0], tip[2])}


def newton_hemisphere(n: int, project: bool) -> dict:
    from shellform.gridshell.hemisphere import HemisphereSpec, build_hemisphere

    model = build_hemisphere(HemisphereSpec(n, configuration="plane"))
    system = build_rod_system(model.network)
    t0 = time.perf_counter()
    res = solve_incremental(system, n_steps=40, paths=model.paths, t_end=1.0, rtol=1e-10, max_iter=60, project=project)
    return {"case": f"hemisphere n = {n} by paths ({system.n_dof} DOFs)", "success": res.success, "steps": res.n_steps,
            "iterations": sum(res.iterations), "max_per_step": max(res.iterations, default=0),
            "wall_s": time.perf_counter() - t0, "tip": None}


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--part", nargs="+", choices=["assembly", "tangent", "newton"],
                        default=["assembly", "tangent", "newton"])
    parser.add_argument("--rods", type=int, nargs="+", default=[14, 30], help="rods per direction")
    parser.add_argument("--edges-per-cell", type=int, default=6)
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--axial-ratios", type=float, nargs="+", default=[1e3, 1e5, 1e7, 1e9])
    parser.add_argument("--hemisphere-n", type=int, nargs="*", default=[5])
    args = parser.parse_args()
    if "assembly" in args.part:
        head = ["rods", "dof", "free", "nnz", "rod_stretch", "rod_bend", "rod_twist", "joints", "hinges", "assembly",
                "direct", "ldl"]
        print(" ".join(f"{h:>11}" for h in head) + "   (times in s: gradient + Hessian values per effect;"
              " hinges = bending and twisting Hessian values in one pass;"
              " assembly = residual + free tangent; solve = factorise + solve)")
        for n in args.rods:
            r = run(n, args.edges_per_cell, args.repeat)
            print(" ".join(f"{r[h]:11d}" if isinstance(r[h], (int, np.integer)) else f"{r[h]:11.4f}" for h in head),
                  flush=True)
    if "tangent" in args.part:
        head = ["n", "free", "nnz", "rod_stretch", "rod_bend", "rod_twist", "joints", "hinges", "tangent", "cholesky",
                "ldl", "ratio", "interleaved"]
        print(" ".join(f"{h:>11}" for h in head) + "   (times in ms: Hessian values per effect; hinges = bending and"
              " twisting in one pass; tangent = free tangent;"
              " numeric refactorisation; ratio = tangent / Cholesky refactorisation; interleaved = median of that ratio over"
              " tangents and refactorisations taken alternately)")
        for n in args.hemisphere_n:
            r = hemisphere_tangent(n, args.repeat)
            print(" ".join(f"{r[h]:11d}" if isinstance(r[h], (int, np.integer)) else
                           f"{r[h]:11.3f}" if h in ("ratio", "interleaved") else f"{1e3 * r[h]:11.3f}" for h in head),
                  flush=True)
    if "newton" in args.part:
        print("static Newton, straight line search (projection off) against the stretch projection (on)")
        cases = [(newton_cantilever, a) for a in args.axial_ratios] + [(newton_hemisphere, n) for n in args.hemisphere_n]
        for fn, arg in cases:
            for project in (False, True):
                r = fn(arg, project)
                tip = "" if r["tip"] is None else f"  tip ({r['tip'][0]:.6f}, {r['tip'][1]:.6f})"
                print(f"  {r['case']:42s} projection {'on ' if project else 'off'}: success {r['success']!s:5} "
                      f"steps {r['steps']:4d}  Newton {r['iterations']:5d} (max {r['max_per_step']:3d} per step)  "
                      f"wall {r['wall_s']:7.2f} s{tip}", flush=True)


if __name__ == "__main__":
    main()
