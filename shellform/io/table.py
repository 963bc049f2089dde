"""Tables (CSV) and curves (PNG) written atomically."""

from __future__ import annotations

import csv
import os
import tempfile
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np


def _temporary(path: Path, suffix: str) -> str:
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}-", suffix=suffix, dir=path.parent)
    os.close(fd)
    return tmp


def _cell(v):
    if isinstance(v, (bool, np.bool_)):
        return int(v)  # 1/0 reads back as a number everywhere
    if isinstance(v, (float, np.floating)):
        return f"{v:.10g}"
    return v


def write_csv(path, table: Mapping[str, Sequence], columns: Sequence[str] | None = None) -> Path:
    """Write equal-length columns as CSV with a header row."""
    path = Path(path)
    columns = list(columns or table.keys())
    lengths = {len(table[c]) for c in columns}
    if len(lengths) > 1:
        raise ValueError(f"columns have different lengths: {sorted(lengths)}")
    tmp = _temporary(path, ".csv")
    try:
        with open(tmp, "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(columns)
            for row in zip(*(table[c] for c in columns)):
                w.writerow([_cell(v) for v in row])
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
    return path


def read_csv(path) -> dict[str, np.ndarray]:
    """Read a CSV written by :func:`write_csv`: numeric columns as floats, others as strings."""
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    head, body = rows[0], rows[1:]
    out = {}
    for i, c in enumerate(head):
        col = [r[i] for r in body]
        try:
            out[c] = np.array([float(v) for v in col])
        except ValueError:
            out[c] = np.array(col)
    return out


def plot_curve(path, x, y, xlabel: str, ylabel: str, title: str = "", marks=(), stable=None) -> Path:
    """Plot a load-displacement curve to PNG.

    Parameters
    ----------
    marks : iterable of (x, y, label)
        Points to mark (limit points, bifurcations, snaps).
    stable : array of bool, optional
        Draw stable parts solid and unstable parts dashed.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    path = Path(path)
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    fig, ax = plt.subplots(figsize=(6.4, 4.4), dpi=120)
    if stable is None:
        ax.plot(x, y, "-", color="C0", lw=1.5)
    else:
        stable = np.asarray(stable, dtype=bool)
        ys = np.where(stable, y, np.nan)
        yu = np.where(~stable | np.r_[~stable[1:], False] | np.r_[False, ~stable[:-1]], y, np.nan)
        ax.plot(x, yu, "--", color="C3", lw=1.2, label="unstable")
        ax.plot(x, ys, "-", color="C0", lw=1.5, label="stable")
        ax.legend(loc="best")
    for mx, my, label in marks:
        ax.plot([mx], [my], "o", color="k", ms=4)
        ax.annotate(label, (mx, my), textcoords="offset points", xytext=(4, 4), fontsize=8)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    if title:
        ax.set_title(title)
    ax.grid(True, alpha=0.3)
    fig.tight_layout()
    tmp = _temporary(path, ".png")
    try:
        fig.savefig(tmp)
        os.replace(tmp, path)
    finally:
        plt.close(fig)
        if os.path.exists(tmp):
            os.unlink(tmp)
    return path
