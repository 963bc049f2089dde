"""The table of a sweep: one row per case, its columns, and the plot of one column against a parameter.

A case's row is its swept values, its ``status`` (``finished``, ``failed``,
``interrupted``), and the scalar entries of its summary, nested ones by
their dotted path (``buckling.critical_load_factor``). Axis labels carry a
unit only where one is known: a parameter's from the scene reference, a
result's from the ``units`` block of the case summaries. A key with no
known unit is labelled bare.
"""

from __future__ import annotations

import time
from pathlib import Path

from ..errors import SceneError
from .sweep_cases import Case

#: the summary entries that say what a case is, not what it computed: not columns
_NOT_COLUMNS = ("title", "units")
#: plotted against the first parameter when ``--plot`` is not given, the first of these present
DEFAULT_PLOT = ("max_displacement", "rise", "iterations")


def scalars(summary: dict, prefix: str = "") -> dict:
    """The scalar entries of a summary, nested ones by their dotted path (the columns of the sweep table).

    A form-and-buckle case's critical load factor is ``buckling.critical_load_factor``;
    lists and arrays are left to the case's own files, and an entry with no
    value (``None``) is left out rather than written as a number.
    """
    out = {}
    for k, v in summary.items():
        if not prefix and k in _NOT_COLUMNS:
            continue
        if isinstance(v, dict):
            out.update(scalars(v, f"{prefix}{k}."))
        elif isinstance(v, (bool, int, float, str)):
            out[f"{prefix}{k}"] = v
    return out


def summary_units(summary: dict) -> dict[str, str]:
    """The units a summary gives for its entries, by dotted column name (empty when it gives none)."""
    block = summary.get("units")
    if not isinstance(block, dict):
        return {}
    return {k: v for k, v in scalars(block).items() if isinstance(v, str) and v}


def parameter_unit(key: str) -> str:
    """The unit the scene reference gives a swept key (``members[0].EA`` -> ``N``), or ``""``."""
    from ..scene.format import SCENE
    from ..scene.schema import Key, Table
    from .sweep_cases import parse_path

    node = SCENE
    for part in parse_path(key):
        if isinstance(part, int):
            continue  # an entry of an array of tables has the table's keys
        if not isinstance(node, Table) or part not in node.keys:
            return ""
        node = node.keys[part]
    return node.unit if isinstance(node, Key) else ""


def axis_label(key: str, unit: str) -> str:
    return f"{key} [{unit}]" if unit else key


def case_row(case: Case, summary: dict) -> dict:
    """The row of one case: its values, status and message first, then its summary's scalars."""
    entries = scalars(summary)
    status = entries.pop("run_status", "failed")
    row = {"case": case.name, **case.assignment, "status": status}
    row.update({k: v for k, v in entries.items() if k not in row})
    return row


class SweepTable:
    """The rows of a sweep so far, rewritten to ``sweep.csv`` and ``sweep.json`` as cases finish.

    Both files are written atomically: a sweep killed at any moment leaves
    the rows of every case finished before the last write.
    """

    def __init__(self, out: Path, keys: list[str], n_cases: int):
        self.out = Path(out)
        self.keys = list(keys)
        self.n_cases = n_cases
        self.rows: dict[int, dict] = {}
        #: the units the case summaries give, by dotted name (only those of columns are used)
        self.units: dict[str, str] = {}
        self.kept: list[str] = []
        self.t0 = time.perf_counter()

    def add(self, case: Case, summary: dict, kept: bool = False) -> dict:
        """Add the row of a finished case and rewrite the table; returns the row."""
        row = case_row(case, summary)
        self.rows[case.index] = row
        for k, v in summary_units(summary).items():
            self.units.setdefault(k, v)
        if kept:
            self.kept.append(case.name)
        self.write()
        return row

    @property
    def ordered(self) -> list[dict]:
        return [self.rows[i] for i in sorted(self.rows)]

    @property
    def columns(self) -> list[str]:
        first = ["case", *self.keys, "status"]
        rest = sorted({k for r in self.rows.values() for k in r} - set(first))
        return first + rest

    def column_units(self) -> dict[str, str]:
        """The known unit of each column: a parameter's from the scene reference, a result's from the summaries."""
        units = {k: parameter_unit(k) for k in self.keys}
        units.update({c: self.units[c] for c in self.columns if c in self.units and c not in units})
        return {c: u for c, u in units.items() if u}

    def write(self) -> None:
        from ..io import write_json
        from ..io.table import write_csv

        rows, columns, units = self.ordered, self.columns, self.column_units()
        write_csv(self.out / "sweep.csv", {c: [r.get(c, "") for r in rows] for c in columns}, columns, units=units)
        write_json(self.out / "sweep.json", {
            "parameters": self.keys, "cases": self.n_cases, "done": len(rows), "kept": sorted(self.kept),
            "wall_time_s": time.perf_counter() - self.t0, "units": units, "rows": rows})

    def plot(self, y: str | None, title: str, progress) -> Path | None:
        """Draw ``sweep.png``: column ``y`` (default: see :data:`DEFAULT_PLOT`) against the first parameter.

        Cases without a number in either column (a failed case, a buckling
        load beyond the traced range) are left out and counted in the
        progress report.

        Raises
        ------
        SceneError
            ``y`` is not a column of the table; the message lists the ones there are.
        """
        from ..io.table import plot_curve

        columns, units = self.columns, self.column_units()
        if y is not None and y not in columns:
            known = ", ".join(c for c in columns if c != "case")
            raise SceneError("--plot", f"no entry {y!r} in the case summaries (the table is in "
                                       f"{self.out / 'sweep.csv'}); known: {known}")
        y = y or next((c for c in DEFAULT_PLOT if c in columns), None)
        if y is None:
            return None
        x = self.keys[0]
        number = (int, float)
        points = [(r[x], r[y]) for r in self.ordered
                  if isinstance(r.get(x), number) and not isinstance(r.get(x), bool)
                  and isinstance(r.get(y), number)]
        left_out = len(self.rows) - len(points)
        if not points:
            progress(f"sweep.png not drawn: no case has a number in both {x!r} and {y!r}")
            return None
        if left_out:
            progress(f"sweep.png: {left_out} case(s) without a number in {x!r} or {y!r} left out")
        try:
            return plot_curve(self.out / "sweep.png", [p[0] for p in points], [p[1] for p in points],
                              axis_label(x, units.get(x, "")), axis_label(y, units.get(y, "")),
                              f"{title}: {y} against {x}")
        except Exception as exc:  # noqa: BLE001 (the table is written; a plot that fails is only reported)
            progress(f"sweep.png not drawn: {type(exc).__name__}: {exc}")
            return None
