"""Result tables of the rod validation scripts: one CSV and one Markdown file per study."""

from __future__ import annotations

import csv
import io
from collections.abc import Callable, Sequence
from pathlib import Path

from shellform.io.files import write_text

OUT = Path(__file__).parent / "results"

#: a Markdown column: header, row key, formatter of the value, right-aligned
Column = tuple[str, str, Callable[[object], str], bool]


def fmt(spec: str) -> Callable[[object], str]:
    """Formatter for a format spec such as ``".3e"``."""
    return lambda v: format(v, spec)


def write_results(stem: str, rows: Sequence[dict], title: str, intro: str, columns: Sequence[Column]) -> None:
    """Write ``results/<stem>.csv`` (every key of the rows) and ``results/<stem>.md`` (the chosen columns)."""
    OUT.mkdir(exist_ok=True)
    table = io.StringIO()
    w = csv.DictWriter(table, fieldnames=list(rows[0]), lineterminator="\n")
    w.writeheader()
    w.writerows(rows)
    write_text(OUT / f"{stem}.csv", table.getvalue())
    lines = [f"# {title}\n\n{intro}\n\n", "| " + " | ".join(c[0] for c in columns) + " |\n",
             "|" + "|".join("---:" if c[3] else "---" for c in columns) + "|\n"]
    lines += ["| " + " | ".join(c[2](r[c[1]]) for c in columns) + " |\n" for r in rows]
    write_text(OUT / f"{stem}.md", "".join(lines))
