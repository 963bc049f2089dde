"""Tables (CSV) and curves (PNG), written atomically.

:func:`write_csv` and :func:`read_csv` round-trip any table of equal-length
columns exactly (floats are written with ``repr``). :func:`plot_curve` draws a
force-displacement curve with its stable and unstable parts and marked
points; :func:`write_path_csv` and :func:`plot_path` apply them to the table of
a traced equilibrium path.
"""

from __future__ import annotations

import csv
import textwrap
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .files import open_atomic
from .units import bare_name, header, path_units


def _cell(v):
    if isinstance(v, (bool, np.bool_)):
        return int(v)  # 1/0 reads back as a number everywhere
    if isinstance(v, (int, np.integer)):
        return int(v)
    if isinstance(v, (float, np.floating)):
        return repr(float(v))  # shortest text that reads back to the same double
    return v


def write_csv(path, table: Mapping[str, Sequence], columns: Sequence[str] | None = None,
              units: Mapping[str, str] | None = None) -> Path:
    """Write equal-length columns as CSV with a header row.

    Parameters
    ----------
    table : mapping of column name to sequence
    columns : sequence of str, optional
        Columns to write, in order (default: all of ``table``).
    units : mapping of column name to unit, optional
        Written into the header as ``name [unit]``.

    Returns
    -------
    Path
        The file written.
    """
    path = Path(path)
    columns = list(columns if columns is not None else table.keys())
    missing = [c for c in columns if c not in table]
    if missing:
        raise KeyError(f"table has no column(s) {missing}; available: {sorted(table)}")
    lengths = {len(table[c]) for c in columns}
    if len(lengths) > 1:
        raise ValueError(f"columns have different lengths: {sorted(lengths)}")
    with open_atomic(path, "w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow([header(c, units) for c in columns])
        for row in zip(*(table[c] for c in columns)):
            w.writerow([_cell(v) for v in row])
    return path


def _column(values: list[str]) -> np.ndarray:
    for dtype in (np.int64, float):
        try:
            return np.array([dtype(v) for v in values], dtype=dtype)
        except ValueError:
            continue
    return np.array(values)


def read_csv(path) -> dict[str, np.ndarray]:
    """Read a CSV written by :func:`write_csv`.

    Columns are keyed by name without their unit. Columns of integers come
    back as integers, other numeric columns as floats (exactly the values
    written), the rest as strings.
    """
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    head, body = [bare_name(h) for h in rows[0]], rows[1:]
    return {c: _column([r[i] for r in body]) for i, c in enumerate(head)}


def _figure(size=(6.4, 4.6)):
    # a Figure with its own Agg canvas: no pyplot state, safe in worker threads
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=size, dpi=120)
    FigureCanvasAgg(fig)
    return fig


def save_figure(fig, path, **kwargs) -> Path:
    """Save a Matplotlib figure as PNG atomically (``kwargs`` go to ``savefig``, e.g. ``dpi``)."""
    path = Path(path)
    with open_atomic(path, "wb") as fh:
        fig.savefig(fh, format="png", **kwargs)
    return path


#: longest text taken from a scene into a plot (a title); the rest is cut
PLOT_TEXT_LIMIT = 200
#: critical points named in the list beside a plot (the rest are in the events file)
MARKS_LISTED = 12


def _cut(text, limit: int = PLOT_TEXT_LIMIT) -> str:
    text = str(text)
    return text if len(text) <= limit else text[: limit - 1] + "\N{HORIZONTAL ELLIPSIS}"


def plain_title(ax, text: str, width: int = 70, **kwargs) -> None:
    """Set a title from user text: shown as typed (no mathtext), cut to a sane length.

    A ``$`` in a scene title would otherwise be parsed as TeX, and bad TeX
    raises only when the figure is drawn, after the analysis; a very long
    title takes minutes to lay out.
    """
    ax.set_title(textwrap.fill(_cut(text), width), parse_math=False, **kwargs)


def _save(fig, path: Path) -> Path:
    # "tight": the list of critical points beside the axes is part of the picture
    return save_figure(fig, path, bbox_inches="tight")


@dataclass(frozen=True)
class CurveStyle:
    """How a curve's points are drawn and marked (see :func:`plot_curve`).

    Attributes
    ----------
    marks : sequence of (x, y, label)
        Points to mark (limit points, bifurcations, snaps): numbered on the
        curve and named in a list beside it.
    stable : array of bool, optional
        Stable points; a segment touching an unstable point is drawn dashed.
    branch : array of int, optional
        Branch (or segment) of every point: one colour per branch, and no
        line is drawn between points of different branches.
    reference : (x, y), optional
        A reference curve (an analytic solution) drawn in grey underneath.
    branch_name : str
        What the legend calls a branch ("segment" for the stable stretches of
        an indentation between snaps).
    """

    marks: Sequence = ()
    stable: np.ndarray | None = None
    branch: np.ndarray | None = None
    reference: tuple[np.ndarray, np.ndarray] | None = None
    branch_name: str = "branch"


def _runs(stable: np.ndarray, branch: np.ndarray):
    """Runs ``(start, stop, branch, unstable)`` of consecutive segments alike in branch and stability."""
    seg_unstable = ~(stable[:-1] & stable[1:])
    seg_branch = branch[1:]
    joined = branch[1:] == branch[:-1]
    start, n_seg = 0, len(stable) - 1
    while start < n_seg:
        if not joined[start]:
            start += 1
            continue
        stop = start
        while stop + 1 < n_seg and joined[stop + 1] and seg_unstable[stop + 1] == seg_unstable[start] \
                and seg_branch[stop + 1] == seg_branch[start]:
            stop += 1
        yield start, stop, int(seg_branch[start]), bool(seg_unstable[start])
        start = stop + 1


def _draw_runs(ax, x, y, style: CurveStyle) -> bool:
    """Draw the curve run by run; returns whether the legend has entries."""
    show_stability = style.stable is not None
    stable = np.ones(len(x), dtype=bool) if style.stable is None else np.asarray(style.stable, dtype=bool)
    branch = np.zeros(len(x), dtype=int) if style.branch is None else np.asarray(style.branch, dtype=int)
    colors = ["C0", "C1", "C2", "C4", "C5"]
    labelled = set()
    for start, stop, b, unstable in _runs(stable, branch):
        label = None
        if (b, unstable) not in labelled and (show_stability or branch.max() > 0):
            words = ("unstable" if unstable else "stable") if show_stability else ""
            label = words if branch.max() == 0 else f"{style.branch_name} {b}" + (f", {words}" if words else "")
            labelled.add((b, unstable))
        ax.plot(x[start:stop + 2], y[start:stop + 2], ls="--" if unstable else "-",
                color=colors[b % len(colors)], lw=1.5, label=label, zorder=2)
    return bool(labelled)


def _draw_marks(ax, marks) -> None:
    # marks are numbered on the curve and named in a list beside it, so that many never overlap
    for k, (mx, my, label) in enumerate(marks):
        ax.plot([mx], [my], "o", mfc="none", mec="red", ms=8, zorder=4)
        ax.annotate(str(k + 1), (mx, my), textcoords="offset points", xytext=(4, 4), fontsize=7, color="red")
    if marks:
        shown = [_cut(m[2], 60) for m in marks[:MARKS_LISTED]]
        if len(marks) > MARKS_LISTED:
            shown.append(f"... {len(marks) - MARKS_LISTED} more (see the events file)")
        ax.text(1.02, 1.0, "\n".join(shown), transform=ax.transAxes, va="top", ha="left", fontsize=7,
                parse_math=False)


def plot_curve(path, x, y, xlabel: str, ylabel: str, title: str = "", style: CurveStyle = CurveStyle()) -> Path:
    """Plot a load-displacement curve to PNG: stable parts solid, unstable dashed, points marked (``style``)."""
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    fig = _figure()
    ax = fig.add_subplot(1, 1, 1)
    if style.reference is not None:
        ax.plot(style.reference[0], style.reference[1], color="0.6", lw=3, alpha=0.6, label="reference", zorder=1)
    legend = _draw_runs(ax, x, y, style)
    ax.plot(x, y, ".", color="k", ms=2.5, zorder=3)
    _draw_marks(ax, list(style.marks))
    # labels may come from a user too (sweep parameters): shown as typed, like the title
    ax.set_xlabel(_cut(xlabel), parse_math=False)
    ax.set_ylabel(_cut(ylabel), parse_math=False)
    if title:
        plain_title(ax, title, fontsize=9)
    ax.grid(True, alpha=0.3)
    if legend or style.reference is not None:
        ax.legend(fontsize=8, loc="best")
    fig.tight_layout()
    return _save(fig, Path(path))


# -- equilibrium paths ------------------------------------------------------------------


def path_columns(result) -> list[str]:
    """Default CSV columns of a traced path: the standard table columns, then the monitors."""
    from ..solvers.continuation import TABLE_COLUMNS

    return list(TABLE_COLUMNS) + list(result.monitors)


def write_path_csv(result, path, columns: Sequence[str] | None = None) -> Path:
    """Write the table of a :class:`~shellform.solvers.continuation.ContinuationResult`, one row per point."""
    return write_csv(path, result.table, list(columns) if columns is not None else path_columns(result),
                     units=path_units(result.control, result.monitors))


read_path_csv = read_csv


@dataclass(frozen=True)
class PathPlot:
    """The force-displacement plot of a traced path (see :func:`plot_path`).

    Attributes
    ----------
    file : str
        File name in the output folder (default ``{name}.png`` of the run).
    x, y : str
        Columns of the path table: abscissa (a monitor or ``displacement``) and ordinate.
    xlabel, ylabel, title : str, optional
        Labels (defaults: the columns, no title).
    event_x : callable, optional
        ``event_x(event)``: the abscissa of an event when ``x`` is a monitor
        (else events of such a plot are not marked).
    """

    file: str = ""
    x: str = "displacement"
    y: str = "load"
    xlabel: str | None = None
    ylabel: str | None = None
    title: str | None = None
    event_x: Callable | None = None


def plot_path(result, path, plot: PathPlot = PathPlot(), reference: tuple[np.ndarray, np.ndarray] | None = None
              ) -> Path:
    """Force-displacement plot of a traced path (PNG).

    Stable stretches (no negative eigenvalue) are drawn solid, unstable ones
    dashed, one colour per branch; limit and bifurcation points are numbered.
    ``reference = (x, y)`` adds a curve (an analytic solution) in grey.
    """
    x, y = plot.x, plot.y
    table = result.table
    xs, ys = list(np.asarray(table[x], dtype=float)), list(np.asarray(table[y], dtype=float))
    stable = list(np.asarray(table["n_negative"]) == 0)
    branch = list(np.asarray(table["branch"], dtype=int))
    steps = list(np.asarray(table["step"], dtype=int))
    marks = []
    for k, e in enumerate(result.events):
        ex = plot.event_x(e) if plot.event_x is not None else getattr(e, x, None)
        ey = getattr(e, y, None)
        if ex is None or ey is None:
            continue
        marks.append((float(ex), float(ey), f"{k + 1}: {e.kind} point at {y} {float(ey):.4g}"))
        # the critical point splits the step it lies in: stable up to it, unstable after it
        # (a step that crosses it is not drawn dashed from its start)
        at = next((i for i, st in enumerate(steps) if st == e.step), None)
        if at is not None and at > 0 and branch[at] == branch[at - 1]:
            xs.insert(at, float(ex))
            ys.insert(at, float(ey))
            stable.insert(at, True)
            branch.insert(at, branch[at])
            steps.insert(at, -1)
    style = CurveStyle(marks=marks, stable=np.asarray(stable), branch=np.asarray(branch), reference=reference)
    return plot_curve(path, xs, ys, plot.xlabel or x, plot.ylabel or y, plot.title or "", style)
