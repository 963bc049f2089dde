"""The ``shellform`` command."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from .errors import SceneError, ShellformError
from .api import builtin_scene_path, builtin_scenes
from .progress import Console

DEFAULT_SCENE = "default"


def _scene_path(arg: str | None) -> Path:
    """A scene file, or the built-in scene of that name (default: the default scene)."""
    if arg is None:
        return builtin_scene_path(DEFAULT_SCENE)
    path = Path(arg)
    if path.exists() or path.suffix == ".toml":
        return path
    try:
        return builtin_scene_path(arg)
    except SceneError:
        raise SceneError(arg, f"no such file and no built-in scene of that name; built-in: {', '.join(builtin_scenes())}"
                         ) from None


def _verbosity(args) -> int:
    return 0 if args.quiet else 2 if args.verbose else 1


def _cmd_run(args) -> int:
    from .api import run
    from .scene import load_scene

    path = _scene_path(args.scene)
    scene = load_scene(path)
    console = Console(_verbosity(args))
    console(f"scene: {path}")
    try:
        summary = run(scene, args.out, console, resume=args.resume).summary
    finally:
        console.close()
    for note in summary.get("warnings", []):
        console(f"warning: {note}")
    console(f"results in {Path(args.out).resolve()} ({summary['wall_time_s']:.2f} s; log in run.log)")
    return 0 if summary.get("converged", False) else 1


def _cmd_validate(args) -> int:
    from .validation import run_validation

    progress = (lambda msg: None) if args.quiet else (lambda msg: print(msg, file=sys.stderr, flush=True))
    try:
        results = run_validation(args.cases, args.out, progress)
    except KeyError as exc:
        print(f"shellform: error: {exc.args[0]}", file=sys.stderr)
        return 2
    progress(f"report: {Path(args.out).resolve() / 'report.md'}")
    return 0 if all(r.passed for r in results) else 1


def _cmd_sweep(args) -> int:
    from .studies.sweep import SweepOptions, run_sweep

    progress = (lambda msg: None) if args.quiet else (lambda msg: print(msg, file=sys.stderr, flush=True))
    options = SweepOptions(workers=args.workers, scheduler=args.scheduler, rerun=args.rerun, plot_y=args.plot)
    try:
        rows = run_sweep(_scene_path(args.scene), args.param, args.out, progress=progress, options=options)
    except KeyboardInterrupt:
        print(f"shellform: interrupted; the finished cases are in {Path(args.out).resolve() / 'sweep.csv'}, and "
              "the same command runs the rest", file=sys.stderr)
        return 130
    progress(f"table: {Path(args.out).resolve() / 'sweep.csv'}")
    return 0 if all(r.get("converged", False) for r in rows) else 1


def _cmd_study(args) -> int:
    from .studies import StudyOptions, run_imperfection_study

    progress = (lambda msg: None) if args.quiet else (lambda msg: print(msg, file=sys.stderr, flush=True))
    options = StudyOptions(workers=args.workers, scheduler=args.scheduler, rerun=args.rerun)
    try:
        summary = run_imperfection_study(_scene_path(args.scene), args.out, options, progress)
    except KeyboardInterrupt:
        print(f"shellform: interrupted; the finished samples are in {Path(args.out).resolve() / 'study.csv'}, and "
              "the same command runs the rest", file=sys.stderr)
        return 130
    progress(f"table: {Path(args.out).resolve() / 'study.csv'}; figures in study.json")
    return 0 if summary["failed"] == 0 else 1


def _cmd_serve(args) -> int:
    from .hops.server import HopsApp, HopsServer

    server = HopsServer((args.host, args.port), HopsApp(timeout=args.timeout), verbose=args.verbose)
    print(f"shellform Hops server on {server.url}: components {', '.join(server.app.components)}; in Grasshopper, "
          f"point a Hops component at {server.url}/FormFind (Ctrl+C stops the server)", file=sys.stderr, flush=True)
    try:
        server.serve_forever()
    except KeyboardInterrupt:
        pass
    finally:
        server.server_close()
    return 0


def _cmd_schema(args) -> int:
    from .scene.schema import reference
    from .scene.format import SCENE

    print(reference(SCENE))
    return 0


def _runner_arguments(parser, runs: str) -> None:
    """Where the runs of a sweep or a study go (shellform.studies.runner), and whether finished ones run again."""
    parser.add_argument("--workers", type=int, default=2, help=f"local processes (default: 2; 1 runs the {runs} in "
                        "this process)")
    parser.add_argument("--scheduler", default=None, metavar="ADDRESS", help=f"run the {runs} on this Dask "
                        "scheduler instead (needs the extra shellform[sweep])")
    parser.add_argument("--rerun", action="store_true", help=f"run every one of the {runs} again, also those "
                        "finished before")


def main(argv=None) -> int:
    from . import __version__

    parser = argparse.ArgumentParser(prog="shellform", description="Form finding and post-buckling of gridshells.")
    parser.add_argument("--version", action="version", version=f"shellform {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)
    run = sub.add_parser("run", help="run a scene and write results")
    run.add_argument("scene", nargs="?", help="scene TOML file or the name of a built-in scene "
                     "(default: the built-in default scene)")
    run.add_argument("--out", default="results", help="output directory (default: ./results)")
    run.add_argument("-q", "--quiet", action="store_true", help="no progress output")
    run.add_argument("-v", "--verbose", action="store_true", help="every step and iteration on a line of its own "
                     "(default: one status line that updates in place)")
    run.add_argument("--resume", action="store_true", help="continue an interrupted continuation, relaxation or "
                     "time stepping from its checkpoint in DIR")
    run.set_defaults(func=_cmd_run)
    val = sub.add_parser("validate", help="reproduce published and analytic results; write report.md")
    val.add_argument("cases", nargs="*", help="case names (default: all)")
    val.add_argument("--out", default="validation-report", help="output directory (default: ./validation-report)")
    val.add_argument("--quiet", action="store_true", help="no progress output")
    val.set_defaults(func=_cmd_validate)
    sw = sub.add_parser("sweep", help="run a parameter study: one scene, many values, one table")
    sw.add_argument("scene", help="base scene: a TOML file or the name of a built-in scene")
    sw.add_argument("--param", action="append", required=True, metavar="KEY=V1,V2,...",
                    help="scene key path and its values, e.g. members[0].EA=1e3,1e4 (repeatable: all combinations)")
    sw.add_argument("--out", default="sweep", help="output directory (default: ./sweep); a sweep run again into "
                    "it keeps the cases that finished")
    _runner_arguments(sw, "cases")
    sw.add_argument("--plot", default=None, help="summary entry to plot against the first parameter, e.g. "
                    "buckling.critical_load_factor")
    sw.add_argument("--quiet", action="store_true", help="no progress output")
    sw.set_defaults(func=_cmd_sweep)
    study = sub.add_parser("study", help="run a study of many imperfect structures of one scene")
    kinds = study.add_subparsers(dest="kind", required=True)
    imp = kinds.add_parser("imperfection", help="knock-down curves and fractiles of the critical load factor "
                           "(the scene's [study] table; see docs/imperfections.md)")
    imp.add_argument("scene", help="scene: a TOML file or the name of a built-in scene, with a [study] table")
    imp.add_argument("--out", default="study", help="output directory (default: ./study); a study run again into "
                     "it keeps the samples that finished")
    _runner_arguments(imp, "samples")
    imp.add_argument("--quiet", action="store_true", help="no progress output")
    imp.set_defaults(func=_cmd_study)
    serve = sub.add_parser("serve", help="serve shellform's analyses to Grasshopper's Hops component")
    serve.add_argument("--host", default="127.0.0.1", help="address to listen on (default: 127.0.0.1, this machine "
                       "only)")
    serve.add_argument("--port", type=int, default=5000, help="port (default: 5000; 0 picks a free one)")
    serve.add_argument("--timeout", type=float, default=None, help="stop a run after this many seconds (default: "
                       "none; a run also stops when Hops gives up on it)")
    serve.add_argument("-v", "--verbose", action="store_true", help="log every request")
    serve.set_defaults(func=_cmd_serve)
    schema = sub.add_parser("schema", help="print the scene reference (Markdown)")
    schema.set_defaults(func=_cmd_schema)
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except ShellformError as exc:
        print(f"shellform: error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:
        # a folder that cannot be written, a full disk: the system's words, without a traceback
        where = f" ({exc.filename})" if exc.filename else ""
        print(f"shellform: error: {exc.strerror or exc}{where}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("shellform: interrupted; `shellform run ... --resume` continues from the last checkpoint",
              file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
