"""What a sweep costs beyond its cases: the sweep's wall time against the same cases in a plain loop.

The cases are the chain of ``scenes/chain_dynamics.toml`` (implicit Euler time
stepping, fixed step) with ``--duration`` seconds of motion (5 s: about a
second of work each), swept over ``--cases`` values of the damping. The loop
runs every case through ``run_case`` (what a sweep worker runs) in this
process, after one untimed case has imported everything; its per-case wall
times summed are the work. Each sweep runs the same cases into a fresh folder
with ``workers`` = 1 (in this process) and 2 (a process pool). The overhead is
the sweep's wall time less the work shared among the workers, as a share of
that:

    overhead = (wall - work / workers) / (work / workers)

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_sweep.py [--cases 20] [--duration 5.0] [--workers 1 2]
        [--rounds 3] [--start-methods default spawn]

``--start-methods`` runs the pools of every round once per start method:
``default`` is the runner's own choice (``fork`` here unless threads other
than OpenBLAS's are live; see ``shellform/studies/runner.py``), the others
are forced through ``SHELLFORM_START_METHOD``. A ``forkserver`` server starts
once per process, so only the first round pays for its imports.

Each round runs the loop and then the sweeps, and compares them with that
round's loop; the summary gives the median of the rounds. The CPU time (this
process and its workers) is printed beside the wall time, with its excess
over the loop's: it does not count the time a worker waits for a core that
another program holds, which the wall time does. The machine's load average
is printed with each row: on a machine other programs use, read the rows of
low load.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import tomllib

from shellform.studies import runner
from shellform.studies.sweep import run_case, run_sweep
from shellform.studies.sweep_cases import expand, parse_param

ROOT = Path(__file__).resolve().parents[1]
RESULTS = Path(__file__).resolve().parent / "results"


def chain_scene(folder: Path, duration: float) -> Path:
    """The chain scene with ``duration`` seconds of motion, written into ``folder``."""
    text = (ROOT / "scenes" / "chain_dynamics.toml").read_text()
    marker = "duration = 3.0"  # the scene's own line
    if marker not in text:
        raise SystemExit(f"scenes/chain_dynamics.toml has no {marker!r} line to set the duration in")
    path = folder / "chain.toml"
    path.write_text(text.replace(marker, f"duration = {duration!r}"))
    return path


def cpu_seconds() -> float:
    """CPU time of this process and of its children that have ended (a pool's workers, once shut down)."""
    me, kids = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return me.ru_utime + me.ru_stime + kids.ru_utime + kids.ru_stime


#: run in a fresh interpreter: what a spawned worker pays before its first case is as fast as the loop's
_FRESH = """
import sys, time, tomllib
t0 = time.perf_counter()
from shellform.studies.sweep import run_case
t1 = time.perf_counter()
data = tomllib.loads(open(sys.argv[1]).read())
walls = []
for k in range(2):
    t = time.perf_counter()
    run_case(data, sys.argv[2] + str(k), sys.argv[3])
    walls.append(time.perf_counter() - t)
print(t1 - t0, *walls)
"""


def fresh_process(scene: Path, out: Path) -> tuple[float, float, float]:
    """Import time, first and second case of a fresh interpreter, as a spawned worker starts."""
    done = subprocess.run([sys.executable, "-c", _FRESH, str(scene), str(out), str(scene.parent)],
                          capture_output=True, text=True, check=True)
    return tuple(float(v) for v in done.stdout.split()[-3:])


def two_cases(data: dict, out: str, base_dir: str) -> tuple[float, float, float]:
    """In a pool's worker: when it started its task (``time.time``), its first case's and the same case's wall time."""
    started, walls = time.time(), []
    for k in range(2):
        t = time.perf_counter()
        run_case(data, f"{out}_{k}", base_dir)
        walls.append(time.perf_counter() - t)
    return started, walls[0], walls[1]


def pool_start(method: str, case, folder: Path, workers: int) -> tuple[float, float, float]:
    """A pool of ``workers`` started by ``method``, each running the same case twice: the mean time from the
    pool's creation to a worker's first task, and the mean first and second case."""
    tasks = [(w, (case.data, str(folder / f"{method}_{w}"), case.base_dir)) for w in range(workers)]
    with start_method(method):
        t0 = time.time()
        results = [r for _, r in runner.Runner(workers).run(two_cases, tasks, lambda why: SystemExit(why))]
    if any(isinstance(r, BaseException) for r in results):
        raise SystemExit(f"pool ({method}): {results}")
    return (statistics.mean(r[0] - t0 for r in results), statistics.mean(r[1] for r in results),
            statistics.mean(r[2] for r in results))


def plain_loop(cases, folder: Path) -> tuple[float, float, list[float]]:
    """Wall time, CPU time and per-case wall times of the cases run one after the other in this process."""
    walls = []
    c0, t0 = cpu_seconds(), time.perf_counter()
    for case in cases:
        t = time.perf_counter()
        summary = run_case(case.data, str(folder / case.name), case.base_dir)
        walls.append(time.perf_counter() - t)
        if summary.get("run_status") != "finished":
            raise SystemExit(f"{case.name} did not finish: {summary.get('message')}")
    return time.perf_counter() - t0, cpu_seconds() - c0, walls


@contextlib.contextmanager
def start_method(method: str):
    """Pools started by ``method`` inside the block (``default``, ``-``: the runner's own choice)."""
    saved = os.environ.pop(runner.START_METHOD_VARIABLE, None)
    if method not in ("default", "-"):
        os.environ[runner.START_METHOD_VARIABLE] = method
    try:
        yield
    finally:
        os.environ.pop(runner.START_METHOD_VARIABLE, None)
        if saved is not None:
            os.environ[runner.START_METHOD_VARIABLE] = saved


def chosen_method() -> str:
    with start_method("default"):
        return runner.start_method()


def uneven_end(case_walls: list[float], workers: int) -> float:
    """What an even share of work cannot avoid: the cases, with their loop times, handed in order to whichever
    of ``workers`` is free first (as the pool does); the share of the work per worker by which the last one
    ends after it."""
    free = [0.0] * workers
    for wall in case_walls:
        k = free.index(min(free))
        free[k] += wall
    share = sum(case_walls) / workers
    return (max(free) - share) / share


def load() -> str:
    one, five, _ = os.getloadavg()
    return f"{one:.2f} (5 min: {five:.2f})"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", type=int, default=20)
    parser.add_argument("--duration", type=float, default=5.0, help="seconds of motion per case (sets the work)")
    parser.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--start-methods", nargs="+", default=["default"],
                        help="start methods of the pools: default (the runner's choice), fork, forkserver, spawn")
    parser.add_argument("--rounds", type=int, default=3, help="loop and sweeps this many times")
    parser.add_argument("--save", action="store_true", help="also write benchmarks/results/bench_sweep.md")
    args = parser.parse_args(argv)
    damping = ",".join(f"{1.0 + 0.1 * i:.1f}" for i in range(args.cases))
    param = f"analysis.dynamics.damping={damping}"
    lines = []

    def say(text: str = "") -> None:
        lines.append(text)
        print(text, flush=True)

    with tempfile.TemporaryDirectory(prefix="bench_sweep-") as tmp:
        tmp = Path(tmp)
        scene = chain_scene(tmp, args.duration)
        cases = expand(tomllib.loads(scene.read_text()), [parse_param(param)], str(tmp))
        run_case(cases[0].data, str(tmp / "warm-up"), str(tmp))  # imports and first-call costs, untimed
        say(f"{len(cases)} cases: scenes/chain_dynamics.toml, duration {args.duration} s, `{param[:40]}...`; "
            f"{os.cpu_count()} CPUs; the runner's own start method here: {chosen_method()}")
        say()
        say("| round | run | workers | start | wall [s] | work / workers [s] | overhead [s] | overhead | CPU [s] "
            "| CPU overhead | load average before |")
        say("|---:|---|---:|---|---:|---:|---:|---:|---:|---:|---|")
        runs = [(w, "-") for w in args.workers if w == 1]
        runs += [(w, m) for w in args.workers if w > 1 for m in args.start_methods]
        overheads: dict[tuple[int, str], list[tuple[float, float]]] = {run: [] for run in runs}
        walls, uneven = [], {w: [] for w in args.workers if w > 1}
        for r in range(args.rounds):
            before = load()
            loop_wall, loop_cpu, case_walls = plain_loop(cases, tmp / f"loop_{r}")
            walls += case_walls
            work = sum(case_walls)
            for w in uneven:
                uneven[w].append(uneven_end(case_walls, w))
            say(f"| {r + 1} | plain loop | 1 | - | {loop_wall:.2f} | {work:.2f} | - | - | {loop_cpu:.2f} | - "
                f"| {before} |")
            for workers, method in runs:
                before = load()
                with start_method(method):
                    c0, t0 = cpu_seconds(), time.perf_counter()
                    rows = run_sweep(scene, [param], tmp / f"sweep_{r}_{workers}_{method}", workers=workers)
                    wall, cpu = time.perf_counter() - t0, cpu_seconds() - c0
                bad = [row["case"] for row in rows if row["status"] != "finished"]
                if bad:
                    raise SystemExit(f"sweep with {workers} workers ({method}): cases {bad} did not finish")
                share = work / workers
                over, cpu_over = (wall - share) / share, (cpu - loop_cpu) / loop_cpu
                overheads[workers, method].append((over, cpu_over))
                say(f"| {r + 1} | sweep | {workers} | {method} | {wall:.2f} | {share:.2f} | {wall - share:.2f} | "
                    f"{100 * over:.1f} % | {cpu:.2f} | {100 * cpu_over:.1f} % | {before} |")
        imports, first, second = fresh_process(scene, tmp / "fresh")
        starts = {m: pool_start(m, cases[0], tmp / "pool_start", max(args.workers)) for m in args.start_methods}
        say()
        say(f"cases: {min(walls):.2f} to {max(walls):.2f} s each in the loops (mean {sum(walls) / len(walls):.2f} s); "
            f"load average after: {load()}")
        for (workers, method), values in overheads.items():
            how = "" if method == "-" else f" ({method})"
            say(f"median over {len(values)} round(s), {workers} worker(s){how}: overhead "
                f"{100 * statistics.median(v[0] for v in values):.1f} % of the wall time, "
                f"{100 * statistics.median(v[1] for v in values):.1f} % of the CPU time")
        for w, values in uneven.items():
            say(f"{w} workers given the loop's cases in order: the last ends {100 * statistics.median(values):.1f} % "
                "(median of the rounds) after an even share of the work, with no overhead at all")
        say()
        say(f"a fresh interpreter (as a spawned worker starts): imports {imports:.2f} s, its first case "
            f"{first:.2f} s, the same case again {second:.2f} s: {imports + first - second:.2f} s before it "
            "runs cases as fast as the loop")
        for method, (start, first, second) in starts.items():
            say(f"a pool of {max(args.workers)} ({method}), each worker running the first case twice: "
                f"{start:.3f} s from the pool's creation to a worker's first task, its first case {first:.2f} s, "
                f"the same case again {second:.2f} s")
    if args.save:
        RESULTS.mkdir(exist_ok=True)
        command = "OPENBLAS_NUM_THREADS=1 python benchmarks/bench_sweep.py " + " ".join(argv or sys.argv[1:])
        (RESULTS / "bench_sweep.md").write_text(f"`{command.strip()}`\n\n" + "\n".join(lines) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
