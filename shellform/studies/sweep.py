"""Parameter studies: one scene, many values, each case in its own folder, one table of them all.

``shellform sweep SCENE.toml --param members[0].EA=1e3,1e4 --param analysis.load_factor=1,2``
runs every combination (Cartesian product) as its own scene in ``case_NNN/``
and gathers one table (``sweep.csv``, ``sweep.json``) and a plot (``sweep.png``).

Where the cases run (:mod:`shellform.studies.runner`, which studies share):

- ``workers=1``: one after the other in this process;
- ``workers=N``: on a pool of N local processes (forked from this process
  after it has imported what cases need, where that is safe; see the runner);
- ``scheduler=ADDRESS``: on a Dask cluster (the optional extra
  ``pip install shellform[sweep]``; Dask is imported only then).

The table is rewritten as each case finishes, so a sweep that is killed
keeps the rows of the cases done. Running the sweep again into the same
folder reuses every case whose folder holds a finished ``summary.json`` of
the same scene (``case_NNN/sweep_case.json`` records which), and runs the
rest. A case that fails is a row with ``status = failed`` and the message;
the other cases go on.
"""

from __future__ import annotations

import json
import sys
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

from ..io.files import output_folder, output_lock
from .runner import Runner
from .sweep_cases import Case, expand, parse_param, parse_path, set_value
from .sweep_table import SweepTable, scalars

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

__all__ = ["SweepOptions", "run_sweep", "run_case", "parse_param", "parse_path", "set_value", "scalars"]

#: the file in a case folder that names the scene the case computes
CASE_FILE = "sweep_case.json"

Progress = Callable[[str], None]


@dataclass
class SweepOptions:
    """Where and how the cases of a sweep run (``workers``, ``scheduler``: see :class:`~shellform.studies.runner.Runner`)."""

    #: local processes; 1 runs the cases in this process, one after the other
    workers: int = 2
    #: address of a Dask scheduler (``tcp://host:8786``); then ``workers`` is not used
    scheduler: str | None = None
    #: run every case again, also those a previous sweep into the folder finished
    rerun: bool = False
    #: summary entry to plot against the first parameter (default: see ``sweep_table.DEFAULT_PLOT``)
    plot_y: str | None = None

    def __post_init__(self):
        self.runner = Runner(self.workers, self.scheduler)  # checks the workers


def run_case(data: dict, out_dir: str, base_dir: str) -> dict:
    """Run one scene and return its summary; a failure is returned as a summary, not raised.

    Module-level so that a pool's worker or a Dask worker finds it by name.
    """
    from ..analyses import run_scene
    from ..scene import parse_scene

    try:
        return run_scene(parse_scene(data, base_dir), out_dir)
    except Exception as exc:  # a worker must hand back a row, whatever happened
        return {"run_status": "failed", "converged": False, "message": f"{type(exc).__name__}: {exc}"}


def finished_summary(case: Case, folder: Path) -> dict | None:
    """The summary of ``case`` a previous sweep finished in ``folder``, or None.

    Only a ``summary.json`` with ``run_status = "finished"`` next to a
    case file of the same scene counts: a folder of another case (the values
    changed since) or of a run that was killed or failed is run again.
    """
    try:
        record = json.loads((folder / CASE_FILE).read_text())
        summary = json.loads((folder / "summary.json").read_text())
    except (OSError, ValueError):
        return None
    if not isinstance(record, dict) or record.get("fingerprint") != case.fingerprint or not isinstance(summary, dict):
        return None
    return summary if summary.get("run_status") == "finished" else None


def _mark(case: Case, folder: Path) -> None:
    from ..io import write_json

    values = {k: v if isinstance(v, (bool, int, float, str)) else str(v) for k, v in case.assignment.items()}
    write_json(folder / CASE_FILE, {"case": case.name, "assignment": values, "fingerprint": case.fingerprint})


# -- the sweep ----------------------------------------------------------------------


def run_sweep(scene_path, params: list[str], out_dir, progress: Progress | None = None,
              options: SweepOptions | None = None, **fields) -> list[dict]:
    """Run a parameter study; returns one row per case, in case order.

    Parameters
    ----------
    scene_path : path-like
        The base scene.
    params : list of str
        ``key=v1,v2,...`` specifications.
    out_dir : path-like
        The sweep's folder: ``sweep.csv``, ``sweep.json``, ``sweep.png`` and one
        ``case_NNN`` folder per case. It is locked while the sweep runs.
    progress : callable, optional
        Called with one line per case as it finishes.
    options : SweepOptions, optional
        Where and how the cases run (defaults: :class:`SweepOptions`).
    **fields
        Fields of :class:`SweepOptions` by name (``workers=1``, ``scheduler=...``,
        ``rerun=True``, ``plot_y=...``), over those of ``options``.

    Raises
    ------
    SceneError
        A bad key or value (before any case runs), or a ``plot_y`` that no
        case summary has (after the table is written).
    """
    opts = replace(options or SweepOptions(), **fields)
    from ..scene import load_scene

    progress = progress or (lambda msg: None)
    scene_path = Path(scene_path)
    load_scene(scene_path)  # the base scene must be valid on its own
    raw = tomllib.loads(scene_path.read_text())
    base_dir = str(scene_path.resolve().parent)
    parsed = [parse_param(p) for p in params]
    cases = expand(raw, parsed, base_dir)
    with output_lock(output_folder(out_dir)) as out:
        table = SweepTable(out, [k for k, _ in parsed], len(cases))
        _sweep(cases, out, table, opts, progress, scene_path)
        table.plot(opts.plot_y, scene_path.stem, progress)
        return table.ordered


def _sweep(cases: list[Case], out: Path, table: SweepTable, opts: SweepOptions, progress: Progress,
           scene_path: Path) -> None:
    todo = []
    for case in cases:
        folder = out / case.name
        summary = None if opts.rerun else finished_summary(case, folder)
        if summary is not None:
            table.add(case, summary, kept=True)
            progress(f"  {case.name} {case.assignment}: finished before, kept")
            continue
        output_folder(folder)
        _mark(case, folder)
        todo.append(case)
    progress(f"sweep: {len(cases)} cases of {scene_path.name}, {len(todo)} to run {opts.runner.where(len(todo))}")
    tasks = [(case, (case.data, str(out / case.name), case.base_dir)) for case in todo]
    for case, summary in opts.runner.run(run_case, tasks, _died):
        row = table.add(case, summary)
        wall = row.get("wall_time_s")
        took = f" ({wall:.2f} s)" if isinstance(wall, float) else ""
        why = f": {row['message']}" if row["status"] != "finished" and row.get("message") else ""
        progress(f"  {case.name} {case.assignment}: {row['status']}, converged={row.get('converged')}{took}{why}")


def _died(why: str) -> dict:
    return {"run_status": "failed", "converged": False, "message": f"the worker running the case died: {why}"}
