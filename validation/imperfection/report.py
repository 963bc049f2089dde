"""Markdown pieces shared by the imperfection validation reports."""

from __future__ import annotations


def knockdown_table(study: dict) -> list[str]:
    """The knock-down factor of every mode and sign (columns) at every amplitude (rows) of a modes study."""
    curves = study["knockdown"]
    lines = ["| amplitude / span | " + " | ".join(curves) + " |", "|---|" + "---|" * len(curves)]
    for a in study["amplitudes"]:
        cells = []
        for c in curves.values():
            k = dict(zip(c["amplitude"], c["knockdown"])).get(a)
            cells.append("no critical point" if k is None else f"{k:.4f}")
        lines.append(f"| {a:.3g} | " + " | ".join(cells) + " |")
    return lines
