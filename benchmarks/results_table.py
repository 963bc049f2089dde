"""Writing a benchmark's results: its Markdown table printed and saved, its rows as JSON."""

from __future__ import annotations

import json
from pathlib import Path

RESULTS = Path(__file__).resolve().parent / "results"


def write_results(name: str, lines: list[str], rows: list[dict]) -> None:
    """Print ``lines`` and save them as ``results/<name>.md``, with ``rows`` as ``results/<name>.json``."""
    text = "\n".join(lines)
    print(text)
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / f"{name}.md").write_text(text + "\n")
    (RESULTS / f"{name}.json").write_text(json.dumps(rows, indent=1) + "\n")
