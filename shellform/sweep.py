"""Parameter studies: one scene, many values, run in parallel with Dask.

``shellform sweep SCENE.toml --param members[0].EA=1e3,1e4 --param analysis.load_factor=1,2``
runs every combination (Cartesian product) as its own scene in its own
directory, on a local Dask cluster or on any scheduler given by address, and
gathers one table (``sweep.csv``, ``sweep.json``) and a plot (``sweep.png``).
Dask is an optional extra (``pip install shellform[sweep]``).
"""

from __future__ import annotations

import copy
import itertools
import re
import sys
import time
from pathlib import Path

from .errors import SceneError
from .io.files import output_folder, output_lock

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

_TOKEN = re.compile(r"([^.\[\]]+)|\[(\d+)\]")


def parse_path(key: str) -> list:
    """``"members[0].EA"`` -> ``["members", 0, "EA"]``."""
    parts, pos = [], 0
    key = key.strip()
    for m in _TOKEN.finditer(key):
        if m.start() != pos and key[pos:m.start()] != ".":
            raise SceneError(key, "not a valid key path (use dotted names and [index], e.g. members[0].EA)")
        parts.append(m.group(1) if m.group(1) is not None else int(m.group(2)))
        pos = m.end()
    if not parts or pos != len(key):
        raise SceneError(key, "not a valid key path (use dotted names and [index], e.g. members[0].EA)")
    return parts


def parse_param(spec: str) -> tuple[str, list]:
    """``"key=v1,v2,..."`` -> (key, [values]); values are read as TOML values."""
    if "=" not in spec:
        raise SceneError(spec, "a sweep parameter is written key=v1,v2,...")
    key, text = spec.split("=", 1)
    parse_path(key)
    values = []
    for item in text.split(","):
        try:
            values.append(tomllib.loads(f"v = {item.strip()}")["v"])
        except tomllib.TOMLDecodeError:
            values.append(item.strip())  # a bare word is a string
    if not values or values == [""]:
        raise SceneError(key, "needs at least one value")
    return key.strip(), values


def set_value(data: dict, key: str, value) -> None:
    """Set ``value`` at the key path ``key`` of a raw scene dictionary."""
    parts = parse_path(key)
    node = data
    for i, p in enumerate(parts[:-1]):
        try:
            node = node[p]
        except (KeyError, IndexError, TypeError):
            where = "".join(f"[{q}]" if isinstance(q, int) else f".{q}" for q in parts[: i + 1]).lstrip(".")
            raise SceneError(key, f"the scene has no {where!r} to set a value in") from None
    try:
        node[parts[-1]] = value
    except (IndexError, TypeError):
        raise SceneError(key, "the scene has no such entry") from None


def expand(raw: dict, params: list[tuple[str, list]], base_dir=None) -> list[tuple[dict, dict]]:
    """All combinations as (assignment, scene) pairs; each scene is validated now.

    ``base_dir`` is the folder relative file names of the scene are relative to.
    """
    from .scene import parse_scene

    out = []
    keys = [k for k, _ in params]
    for combo in itertools.product(*(v for _, v in params)):
        data = copy.deepcopy(raw)
        for k, v in zip(keys, combo):
            set_value(data, k, v)
        assignment = dict(zip(keys, combo))
        try:
            parse_scene(data, base_dir)
        except SceneError as exc:
            raise SceneError(exc.key, f"{exc.problem} (in the sweep case {assignment})") from None
        out.append((assignment, data))
    return out


def _run_case(data: dict, out_dir: str, base_dir: str) -> dict:
    """Run one scene (in a worker) and return its summary; failures are reported, not raised."""
    from .analyses import run_scene
    from .scene import parse_scene

    try:
        return run_scene(parse_scene(data, base_dir), out_dir)
    except Exception as exc:  # a worker must hand back a row, whatever happened
        return {"converged": False, "message": f"{type(exc).__name__}: {exc}"}


def _scalars(summary: dict, prefix: str = "") -> dict:
    """The scalar entries of a summary, nested ones by their dotted path (the columns of the sweep table).

    A form-and-buckle case's critical load factor is ``buckling.critical_load_factor``;
    lists and arrays are left to the case's own files.
    """
    out = {}
    for k, v in summary.items():
        if not prefix and k == "title":
            continue
        if isinstance(v, dict):
            out.update(_scalars(v, f"{prefix}{k}."))
        elif isinstance(v, (bool, int, float, str)):
            out[f"{prefix}{k}"] = v
    return out


def run_sweep(scene_path, params: list[str], out_dir, scheduler: str | None = None, workers: int = 2,
              progress=None, plot_y: str | None = None) -> list[dict]:
    """Run a parameter study; returns one row per case.

    Parameters
    ----------
    scene_path : path-like
        The base scene.
    params : list of str
        ``key=v1,v2,...`` specifications.
    scheduler : str, optional
        Address of a Dask scheduler; default a local cluster of ``workers``
        single-threaded processes.
    plot_y : str, optional
        Summary entry to plot against the first parameter (default: the
        first of ``max_displacement``, ``rise``, ``iterations`` present).
    """
    try:
        import dask.distributed  # noqa: F401
    except ImportError:  # pragma: no cover
        raise SceneError("sweep", "needs Dask: pip install 'shellform[sweep]'") from None
    from .scene import load_scene

    progress = progress or (lambda msg: None)
    scene_path = Path(scene_path)
    load_scene(scene_path)  # the base scene must be valid on its own
    raw = tomllib.loads(scene_path.read_text())
    base_dir = str(scene_path.resolve().parent)
    cases = expand(raw, [parse_param(p) for p in params], base_dir)
    with output_lock(output_folder(out_dir)) as out:
        return _sweep(cases, params, out, scene_path, base_dir, scheduler, workers, progress, plot_y)


def _sweep(cases, params, out: Path, scene_path: Path, base_dir: str, scheduler, workers, progress, plot_y):
    from dask.distributed import Client, LocalCluster

    from .io import write_json
    from .io.table import plot_curve, write_csv

    progress(f"sweep: {len(cases)} cases of {scene_path.name}")
    t0 = time.perf_counter()
    if scheduler:
        client = Client(scheduler)
        cluster = None
    else:
        cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None)
        client = Client(cluster)
    try:
        futures = [client.submit(_run_case, data, str(out / f"case_{i:03d}"), base_dir, pure=False)
                   for i, (_, data) in enumerate(cases)]
        rows = []
        for i, ((assignment, _), fut) in enumerate(zip(cases, futures)):
            summary = fut.result()
            row = {"case": f"case_{i:03d}", **assignment, **_scalars(summary)}
            rows.append(row)
            progress(f"  {row['case']} {assignment}: converged={summary.get('converged')}")
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
    keys = [k for k, _ in (parse_param(p) for p in params)]
    columns = ["case", *keys] + sorted({k for r in rows for k in r} - {"case", *keys})
    table = {c: [r.get(c, "") for r in rows] for c in columns}
    write_csv(out / "sweep.csv", table, columns)
    write_json(out / "sweep.json", {"parameters": keys, "wall_time_s": time.perf_counter() - t0, "rows": rows})
    if plot_y is not None and plot_y not in columns:
        # the table is written: the work is kept, and the key is refused with the ones there are
        known = ", ".join(c for c in columns if c != "case")
        raise SceneError("--plot", f"no entry {plot_y!r} in the case summaries (the table is in {out / 'sweep.csv'}); "
                         f"known: {known}")
    y = plot_y or next((c for c in ("max_displacement", "rise", "iterations") if c in columns), None)
    first = keys[0]
    if y and all(isinstance(r.get(first), (int, float)) and isinstance(r.get(y), (int, float)) for r in rows):
        try:
            plot_curve(out / "sweep.png", [r[first] for r in rows], [r[y] for r in rows], first, y,
                       f"{scene_path.stem}: {y} against {first}")
        except Exception as exc:  # noqa: BLE001 (the table is written; a plot that fails is only reported)
            progress(f"sweep.png not drawn: {type(exc).__name__}: {exc}")
    elif y:
        progress(f"sweep.png not drawn: {y!r} or {first!r} is not a number in every case")
    return rows
