"""Result tables of the rod validation scripts: one CSV and one Markdown file per study."""

from __future__ import annotations

import csv
from collections.abc import Callable, Sequence
from pathlib import Path

OUT = Path(__file__).parent / "results"

#: a Markdown column: header, row key, formatter of the value, right-aligned
Column = tuple[str, str, Callable[[object], str], bool]


def fmt(spec: str) -> Callable[[object], str]:
    """Formatter for a format spec such as ``".3e"``."""
    return lambda v: format(v, spec)


def write_results(stem: str, rows: Sequence[dict], title: str, intro: str, columns: Sequence[Column]) -> None:
    """Write ``results/<stem>.csv`` (every key of the rows) and ``results/<stem>.md`` (the chosen columns)."""
    OUT.mkdir(exist_ok=True)
    with open(OUT / f"{stem}.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    with open(OUT / f"{stem}.md", "w") as f:
        f.write(f"# {title}\n\n{intro}\n\n")
        f.write("| " + " | ".join(c[0] for c in columns) + " |\n")
        f.write("|" + "|".join("---:" if c[3] else "---" for c in columns) + "|\n")
        for r in rows:
            f.write("| " + " | ".join(c[2](r[c[1]]) for c in columns) + " |\n")
