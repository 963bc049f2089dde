"""Apex indentation of the hemispherical gridshell: arc-length path against the paper's implicit Euler protocol.

1. The whole mode-I curve (dD from 0 to 2R, every snap) for n rods per
   direction at Voronoi length dl, by continuation: build, pre-stress and
   trace times.
2. The same path segment, dD/R from 0 to ``--segment``, computed both ways:
   by continuation, and by the paper's protocol (implicit Euler, time step
   1 ms, apex moved at 1 mm/s, no added damping), giving the ratio of wall
   times. The dynamic run's force at the end of the segment is compared with
   the static one (they should agree: the motion is quasi-static).

    python benchmarks/bench_hemisphere.py [--n 11] [--dl 1.0] [--segment 0.05] [--skip-curve] [--skip-dynamic]
                                          [--newton-only] [--json validation/hemisphere/benchmark.json]

``--newton-only`` also runs the segment's implicit Euler with a Newton
iteration (tangent and factorisation) in every step (``keep_factor=False``).
``--snap-newton 25 40 60 100 [--sizes 5 7 9 11] [--modes I II] [--repeat 1]`` traces whole
curves with the snap dynamics' Newton iterations per time step capped at each value
(``SettleOptions.max_newton``), in fresh processes, and tables the dynamics' steps,
rejected steps and iterations with the thresholds.
``--factor-sizes 5 11 19 29 39 49`` times, at the pre-stressed state of each n, one rod
tangent assembly, one LDL^T factorisation (fresh and numeric refactorisation on the kept
analysis) and one solve, with the factor's fill: what one Newton iteration costs as the net
gets denser.
``--chord-rates off 0.02 0.1 0.5 [--sizes 5 11] [--repeat 2]`` traces whole curves
with the kept factor of implicit Euler (the dynamics through the snaps) off or
at each chord rate, alternating fresh processes.

Times are wall-clock on whatever machine runs it (the reference machine has
2 cores shared with other work).
"""

from __future__ import annotations

import argparse
import json
import time

from shellform.gridshell.hemisphere import HemisphereSpec, build_hemisphere, prestress_on_net
from shellform.gridshell.indentation import indentation_system, trace_indentation


def whole_curve(n, dl):
    t0 = time.perf_counter()
    model = build_hemisphere(HemisphereSpec(n, voronoi_length=dl))
    t1 = time.perf_counter()
    pre = prestress_on_net(model)
    t2 = time.perf_counter()
    setup = indentation_system(model, pre, mode="I")
    res = trace_indentation(setup)
    t3 = time.perf_counter()
    return {
        "n": n, "voronoi_length_mm": dl * 1e3, "dof": res.n_dof, "free": res.n_free,
        "build_s": t1 - t0, "prestress_s": t2 - t1, "trace_s": t3 - t2, "total_s": t3 - t0,
        "success": res.success, "thresholds": [round(t, 4) for t in res.thresholds],
        "max_force": round(res.max_force, 3), "steps": res.steps, "newton_iterations": res.newton_iterations,
        "timings_s": {k: round(v, 2) for k, v in res.timings.items()},
    }


def dynamic_segment(model, pre, d_end, speed=1.0e-3, h=1.0e-3, **options):
    """The paper's protocol over the segment: implicit Euler, apex at ``speed``, from rest in the pre-stressed state."""
    from shellform.solvers.implicit_euler import implicit_euler, lumped_mass

    setup = indentation_system(model, pre, mode="I")
    model.network.frames.restore(setup.frames_state)
    system = setup.system
    calls = []
    tangent_free = system.tangent_free
    system.tangent_free = lambda q: calls.append(1) or tangent_free(q)
    mass = lumped_mass(system.structure, model.network)
    t0 = time.perf_counter()
    dyn = implicit_euler(system, h, d_end / speed, q0=pre.q, mass=mass, damping=0.0, mu=lambda t: speed * t, **options)
    wall = time.perf_counter() - t0
    return dyn, wall, len(calls), setup.force(dyn.q) / setup.force_scale


def segment(n, dl, x_end, speed=1.0e-3, h=1.0e-3, newton_only=False):

    model = build_hemisphere(HemisphereSpec(n, voronoi_length=dl))
    pre = prestress_on_net(model)
    R = model.radius
    d_end = x_end * R
    # continuation over the segment
    setup = indentation_system(model, pre, mode="I")
    t0 = time.perf_counter()
    res = trace_indentation(setup, dD_max=d_end)
    t_cont = time.perf_counter() - t0
    f_static = res.y[-1]
    # implicit Euler: the apex moves at `speed`, the structure starts at rest in the pre-stressed state
    dyn, t_dyn, tangents, f_dyn = dynamic_segment(model, pre, d_end, speed, h)
    out = {
        "segment_dD_over_R": x_end, "dof": res.n_dof,
        "continuation_s": t_cont, "continuation_steps": res.steps,
        "implicit_euler_s": t_dyn, "implicit_euler_steps": dyn.steps, "implicit_euler_success": dyn.success,
        "implicit_euler_newton_iterations": int(sum(dyn.newton_iterations)), "implicit_euler_tangents": tangents,
        "ratio_implicit_euler_over_continuation": t_dyn / t_cont,
        "force_end_continuation": float(f_static), "force_end_implicit_euler": float(f_dyn),
        "whole_path_implicit_euler_steps": int(round(2 * R / speed / h)),
        "whole_path_implicit_euler_estimate_s": t_dyn * 2.0 / x_end,
    }
    if newton_only:
        # the same protocol with a Newton iteration (tangent and factorisation) in every step
        dyn, t_new, tangents, f_new = dynamic_segment(model, pre, d_end, speed, h, keep_factor=False)
        out.update({"newton_only_s": t_new, "newton_only_iterations": int(sum(dyn.newton_iterations)),
                    "newton_only_tangents": tangents, "force_end_newton_only": float(f_new),
                    "ratio_newton_only_over_continuation": t_new / t_cont})
    return out


def chord_rate_curve(variant: str, n: int, dl: float) -> dict:
    """The whole curve with implicit Euler's kept factor off (``variant == "off"``) or at a chord rate."""
    import shellform.solvers.implicit_step as ie

    if variant == "off":
        step = ie.Stepper.step

        def without_kept_factor(self, *args):
            self.kept = None
            return step(self, *args)

        ie.Stepper.step = without_kept_factor
    else:
        ie.CHORD_RATE = float(variant)
    out = whole_curve(n, dl)
    return {"variant": variant, "n": n, "trace_s": out["trace_s"], "thresholds": out["thresholds"],
            "max_force": out["max_force"], "newton_iterations": out["newton_iterations"], "steps": out["steps"]}


def factor_sizes(sizes, dl, repeat=3):
    """Tangent, factorisation and solve times at the pre-stressed state of each n (medians of ``repeat``)."""
    import numpy as np
    import qdldl
    from bench_ldl_backend import median_time as median_of

    from shellform.solvers.factor_base import upper_csc

    def median_time(f):
        return median_of(f, repeat)

    rows = []
    print("| n | DOFs | free | tangent nnz | L nnz | tangent [ms] | fresh LDL^T [ms] | refactorisation [ms] "
          "| solve [ms] |")
    print("|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for n in sizes:
        model = build_hemisphere(HemisphereSpec(n, voronoi_length=dl))
        pre = prestress_on_net(model)
        system = indentation_system(model, pre, mode="I").system
        K = system.tangent_free(pre.q)
        U = upper_csc(K)
        t_tangent = median_time(lambda: system.tangent_free(pre.q))
        t0 = time.perf_counter()
        solver = qdldl.Solver(U, upper=True)
        t_fresh = time.perf_counter() - t0
        t_update = median_time(lambda: solver.update(U, upper=True))
        b = np.ones(K.shape[0])
        t_solve = median_time(lambda: solver.solve(b))
        row = {"n": n, "dof": system.n_dof, "free": K.shape[0], "tangent_nnz": int(K.nnz),
               "L_nnz": int(solver.factors()[0].nnz), "tangent_ms": 1e3 * t_tangent, "fresh_ms": 1e3 * t_fresh,
               "refactor_ms": 1e3 * t_update, "solve_ms": 1e3 * t_solve}
        rows.append(row)
        print(f"| {n} | {row['dof']} | {row['free']} | {row['tangent_nnz']} | {row['L_nnz']} | {row['tangent_ms']:.1f} "
              f"| {row['fresh_ms']:.1f} | {row['refactor_ms']:.1f} | {row['solve_ms']:.2f} |", flush=True)
    return rows


def chord_rates(variants, sizes, dl, repeat):
    """Each variant in its own process, alternating; the table of the median trace times."""
    import statistics
    import subprocess
    import sys

    runs = {}
    for _ in range(repeat):
        for n in sizes:
            for v in variants:
                out = subprocess.run([sys.executable, __file__, "--one-chord-rate", v, "--n", str(n), "--dl", str(dl)],
                                     capture_output=True, text=True, check=True)
                runs.setdefault((n, v), []).append(json.loads(out.stdout.splitlines()[-1]))
    print("| n | chord rate | trace [s] (median) | Newton iterations | thresholds |")
    print("|---:|---|---:|---:|---|")
    for (n, v), rs in runs.items():
        print(f"| {n} | {v} | {statistics.median(r['trace_s'] for r in rs):.1f} | {rs[0]['newton_iterations']} | "
              f"{', '.join(f'{t:.4f}' for t in rs[0]['thresholds'])} |", flush=True)


def snap_newton_curve(cap: int, n: int, dl: float, mode: str) -> dict:
    """The whole curve with the snap dynamics' Newton iterations per time step capped at ``cap``."""
    import functools

    import shellform.gridshell.indentation as indentation
    import shellform.solvers.implicit_euler as ie
    import shellform.solvers.implicit_step as steps

    indentation.SettleOptions = functools.partial(indentation.SettleOptions, max_newton=cap)
    dynamics = {"iterations": 0, "rejected": 0, "steps": 0, "largest": 0}
    integrate, descend = ie.implicit_euler, steps.Stepper._descend

    def descent(*args):
        dynamics["iterations"] += 1  # one Newton iteration of a time step, rejected ones included
        return descend(*args)

    def counted(*args, **kwargs):
        res = integrate(*args, **kwargs)
        dynamics["rejected"] += res.rejected_steps
        dynamics["steps"] += res.steps
        dynamics["largest"] = max([dynamics["largest"], *res.newton_iterations])
        return res

    ie.implicit_euler, steps.Stepper._descend = counted, descent
    model = build_hemisphere(HemisphereSpec(n, voronoi_length=dl))
    setup = indentation_system(model, prestress_on_net(model), mode=mode)
    t0 = time.perf_counter()
    res = trace_indentation(setup)
    return {"cap": cap, "n": n, "mode": mode, "trace_s": time.perf_counter() - t0, "thresholds": list(res.thresholds),
            "max_force": res.max_force, **dynamics}


def snap_newton(caps, sizes, modes, dl, repeat):
    """Whole curves at each cap, each in its own process (alternating); the table of the snap dynamics."""
    import statistics
    import subprocess
    import sys

    runs = {}
    for _ in range(repeat):
        for n in sizes:
            for mode in modes:
                for cap in caps:
                    out = subprocess.run([sys.executable, __file__, "--one-snap-newton", str(cap), mode, "--n", str(n),
                                          "--dl", str(dl)], capture_output=True, text=True, check=True)
                    runs.setdefault((n, mode, cap), []).append(json.loads(out.stdout.splitlines()[-1]))
    print("| n | mode | Newton iterations per step at most | trace [s] (median) | dynamics: steps | rejected | "
          "Newton iterations (rejected steps' included) | most in an accepted step | thresholds dD/R | maximum force |")
    print("|---:|---|---:|---:|---:|---:|---:|---:|---|---:|")
    for (n, mode, cap), rs in runs.items():
        r = rs[0]
        print(f"| {n} | {mode} | {cap} | {statistics.median(x['trace_s'] for x in rs):.2f} | {r['steps']} | "
              f"{r['rejected']} | {r['iterations']} | {r['largest']} | "
              f"{', '.join(f'{t:.5f}' for t in r['thresholds'])} | {r['max_force']:.4f} |", flush=True)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--n", type=int, default=11)
    p.add_argument("--dl", type=float, default=1.0, help="Voronoi length [mm]")
    p.add_argument("--segment", type=float, default=0.05, help="end of the compared segment, dD/R")
    p.add_argument("--skip-curve", action="store_true")
    p.add_argument("--skip-dynamic", action="store_true")
    p.add_argument("--newton-only", action="store_true",
                   help="also run the segment's implicit Euler without the kept factor (keep_factor=False)")
    p.add_argument("--chord-rates", nargs="+", default=None,
                   help="whole curves with implicit Euler's kept factor 'off' or at these chord rates instead")
    p.add_argument("--sizes", type=int, nargs="+", default=[5, 11], help="n of the --chord-rates curves")
    p.add_argument("--repeat", type=int, default=2, help="runs of each --chord-rates variant")
    p.add_argument("--one-chord-rate", default=None, help=argparse.SUPPRESS)
    p.add_argument("--snap-newton", type=int, nargs="+", default=None,
                   help="whole curves with the snap dynamics' Newton iterations per time step capped at these")
    p.add_argument("--modes", nargs="+", default=["I", "II"], help="modes of the --snap-newton curves")
    p.add_argument("--one-snap-newton", nargs=2, default=None, help=argparse.SUPPRESS)
    p.add_argument("--factor-sizes", type=int, nargs="+", default=None,
                   help="time one tangent, factorisation and solve at each of these n instead")
    p.add_argument("--json", default=None, help="also write the results to this JSON file")
    args = p.parse_args(argv)
    if args.one_chord_rate is not None:
        print(json.dumps(chord_rate_curve(args.one_chord_rate, args.n, args.dl * 1e-3)))
        return {}
    if args.one_snap_newton is not None:
        print(json.dumps(snap_newton_curve(int(args.one_snap_newton[0]), args.n, args.dl * 1e-3,
                                           args.one_snap_newton[1])))
        return {}
    if args.snap_newton:
        snap_newton(args.snap_newton, args.sizes, args.modes, args.dl, args.repeat)
        return {}
    if args.chord_rates:
        chord_rates(args.chord_rates, args.sizes, args.dl, args.repeat)
        return {}
    if args.factor_sizes:
        return {"factor_sizes": factor_sizes(args.factor_sizes, args.dl * 1e-3)}
    out = {}
    if not args.skip_curve:
        out["mode_I_whole_curve"] = whole_curve(args.n, args.dl * 1e-3)
        print(json.dumps(out["mode_I_whole_curve"], indent=1), flush=True)
    if not args.skip_dynamic:
        out["segment"] = segment(args.n, args.dl * 1e-3, args.segment, newton_only=args.newton_only)
        print(json.dumps(out["segment"], indent=1), flush=True)
    if args.json:
        import platform

        out["machine"] = {"platform": platform.platform(), "python": platform.python_version()}
        with open(args.json, "w") as fh:
            json.dump(out, fh, indent=1)
    return out


if __name__ == "__main__":
    main()
