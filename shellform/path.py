"""Files of a continuation run: the path table (CSV), the force-displacement plot
(PNG) and the event summary (JSON-ready dict).

All functions are pure apart from the file they write. :func:`run_continuation_case`
ties them to :func:`~shellform.solvers.continuation.trace_path` with a checkpoint,
so that an interrupted run started again with the same arguments resumes.
"""

from __future__ import annotations

import csv
import json
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from .solvers.continuation import TABLE_COLUMNS, ContinuationResult, PathPoint, trace_path

_INT_COLUMNS = {"step", "branch", "n_negative", "iterations"}


def path_columns(result: ContinuationResult) -> list[str]:
    """Default CSV columns: the standard table columns followed by the monitors."""
    return list(TABLE_COLUMNS) + list(result.monitors)


def write_path_csv(result: ContinuationResult, path, columns: Sequence[str] | None = None) -> Path:
    """Write the path table, one row per converged point.

    Parameters
    ----------
    result : ContinuationResult
    path : path-like
        Output file.
    columns : sequence of str, optional
        Columns to write (default :func:`path_columns`).

    Returns
    -------
    Path
        The file written.
    """
    cols = list(columns) if columns is not None else path_columns(result)
    missing = [c for c in cols if c not in result.table]
    if missing:
        raise KeyError(f"path table has no column(s) {missing}; available: {sorted(result.table)}")
    path = Path(path)
    with path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(cols)
        data = [result.table[c] for c in cols]
        for i in range(result.n_points):
            w.writerow([int(d[i]) if c in _INT_COLUMNS else repr(float(d[i])) for c, d in zip(cols, data)])
    return path


def read_path_csv(path) -> dict[str, np.ndarray]:
    """Read a table written by :func:`write_path_csv` into column arrays."""
    with Path(path).open(newline="") as fh:
        rows = list(csv.reader(fh))
    header, body = rows[0], rows[1:]
    out = {}
    for j, name in enumerate(header):
        values = [r[j] for r in body]
        out[name] = np.array(values, dtype=int if name in _INT_COLUMNS else float)
    return out


def plot_path(
    result: ContinuationResult,
    path,
    x: str = "displacement",
    y: str = "load",
    xlabel: str | None = None,
    ylabel: str | None = None,
    title: str | None = None,
    reference: tuple[np.ndarray, np.ndarray] | None = None,
) -> Path:
    """Force-displacement plot of the path (PNG).

    Stable stretches (no negative eigenvalue) are drawn solid, unstable ones
    dashed; limit points are marked with circles, bifurcation points with
    stars. ``reference = (x, y)`` adds a curve (an analytic solution) in grey.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    X, Y = result.table[x], result.table[y]
    n = result.table["n_negative"]
    branch = result.table["branch"]
    fig = Figure(figsize=(6.4, 4.8), dpi=120)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    if reference is not None:
        ax.plot(reference[0], reference[1], color="0.6", lw=3, alpha=0.6, label="reference", zorder=1)
    colors = ["tab:blue", "tab:orange", "tab:green", "tab:purple"]
    labelled = set()
    for i in range(len(X) - 1):
        unstable = max(n[i], n[i + 1]) > 0
        b = int(branch[i + 1])
        key = (b, unstable)
        ax.plot(
            X[i : i + 2], Y[i : i + 2], ls="--" if unstable else "-", color=colors[b % len(colors)], lw=1.6,
            label=None if key in labelled else f"branch {b}, {'unstable' if unstable else 'stable'}", zorder=2,
        )
        labelled.add(key)
    ax.plot(X, Y, ".", color="k", ms=2.5, zorder=3)
    for kind, marker in (("limit", "o"), ("bifurcation", "*")):
        ev = result.events_of(kind)
        if ev:
            ex = [getattr(e, x) if hasattr(e, x) else np.nan for e in ev]
            ey = [getattr(e, y) if hasattr(e, y) else np.nan for e in ev]
            ax.plot(ex, ey, marker, mfc="none" if kind == "limit" else "red", mec="red", ms=9, ls="none",
                    label=f"{kind} point", zorder=4)
    ax.set_xlabel(xlabel or x)
    ax.set_ylabel(ylabel or y)
    if title:
        ax.set_title(title)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path)
    return path


def run_continuation_case(
    system,
    out_dir,
    control: str = "load",
    name: str = "path",
    progress: Callable[[str], None] | None = None,
    resume: bool = True,
    checkpoint_every: int = 10,
    plot: bool = True,
    xlabel: str | None = None,
    ylabel: str | None = None,
    callback: Callable[[PathPoint], bool | None] | None = None,
    **options,
) -> tuple[ContinuationResult, dict]:
    """Trace a path and write its files to ``out_dir``.

    Writes ``{name}.csv`` (path table), ``{name}.png`` (force-displacement
    plot), ``{name}_events.json`` (outcome and events) and keeps
    ``{name}_checkpoint.npz``: started again with the same arguments, an
    interrupted run resumes from its last checkpoint.

    Parameters
    ----------
    system : System
    out_dir : path-like
        Created if missing.
    control : {"load", "displacement"}
    name : str
        Stem of the file names.
    progress : callable, optional
        Receives one line of text per converged point.
    resume : bool
        Continue from an existing checkpoint.
    checkpoint_every : int
        Steps between checkpoints.
    callback : callable, optional
        Also called with each :class:`PathPoint` (for streaming states to a
        mesh writer); returning True stops the run.
    **options
        Passed to :func:`~shellform.solvers.continuation.trace_path`.

    Returns
    -------
    result : ContinuationResult
    summary : dict
        JSON-ready outcome, events and file names (also written to
        ``{name}_events.json``).
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    ck = out / f"{name}_checkpoint.npz"

    def on_point(pt: PathPoint):
        if progress is not None:
            progress(
                f"step {pt.step:4d}  branch {pt.branch}  parameter {pt.parameter: .6e}  load {pt.load: .6e}  "
                f"displacement {pt.displacement: .6e}  negative eigenvalues {pt.n_negative}  "
                f"iterations {pt.iterations}"
            )
        return callback(pt) if callback is not None else None

    result = trace_path(system, control, callback=on_point, checkpoint=ck, checkpoint_every=checkpoint_every,
                        resume=resume, **options)
    files = [write_path_csv(result, out / f"{name}.csv").name]
    if plot:
        default_y = "load factor" if control == "load" else "reaction conjugate to the prescribed displacement"
        files.append(plot_path(result, out / f"{name}.png", xlabel=xlabel or "displacement",
                               ylabel=ylabel or default_y).name)
    summary = result.summary()
    summary["files"] = files + [f"{name}_events.json", ck.name]
    (out / f"{name}_events.json").write_text(json.dumps(summary, indent=2))
    if progress is not None:
        progress(f"{result.message} ({result.steps} steps, {len(result.events)} events)")
    return result, summary
