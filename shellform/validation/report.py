"""Validation results and the report written from them."""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

from ..io import write_json
from ..io.files import output_folder, output_lock, remove_stale_temporaries, write_text


@dataclass
class Check:
    """One computed number against its reference value.

    ``tolerance`` is relative when ``relative`` is True, absolute otherwise.
    """

    quantity: str
    computed: float
    reference: float
    tolerance: float
    relative: bool = True
    source: str = ""

    @property
    def error(self) -> float:
        diff = abs(self.computed - self.reference)
        return diff / abs(self.reference) if self.relative else diff

    @property
    def passed(self) -> bool:
        return bool(self.error <= self.tolerance)

    def to_dict(self) -> dict:
        return {**asdict(self), "error": self.error, "passed": self.passed}


@dataclass
class CaseResult:
    """Outcome of one validation case."""

    name: str
    title: str
    checks: list[Check] = field(default_factory=list)
    figures: list[str] = field(default_factory=list)
    notes: str = ""
    wall_time_s: float = 0.0

    @property
    def passed(self) -> bool:
        return all(c.passed for c in self.checks)


def _markdown(results: list[CaseResult]) -> str:
    n_pass = sum(r.passed for r in results)
    lines = ["# shellform validation report", "",
             f"{n_pass} of {len(results)} cases pass.", "",
             "| case | checks passed | wall time [s] |", "|---|---|---|"]
    for r in results:
        lines.append(f"| {r.name} | {sum(c.passed for c in r.checks)} / {len(r.checks)} | {r.wall_time_s:.2f} |")
    for r in results:
        lines += ["", f"## {r.name}: {r.title}", ""]
        if r.notes:
            lines += [r.notes, ""]
        lines += ["| quantity | computed | reference | error | tolerance | result | source |",
                  "|---|---|---|---|---|---|---|"]
        for c in r.checks:
            kind = "rel." if c.relative else "abs."
            lines.append(
                f"| {c.quantity} | {c.computed:.6g} | {c.reference:.6g} | {c.error:.3g} ({kind}) | "
                f"{c.tolerance:.3g} | {'pass' if c.passed else '**FAIL**'} | {c.source} |"
            )
        for fig in r.figures:
            lines += ["", f"![{Path(fig).stem}]({fig})"]
    return "\n".join(lines) + "\n"


def run_validation(names, out_dir, progress=None) -> list[CaseResult]:
    """Run validation cases and write ``report.md`` and ``validation.json``.

    Parameters
    ----------
    names : list of str
        Case names from :data:`shellform.validation.CASES`; empty for all but
        the long ones that run only when named (``Case.by_name_only``).
    out_dir : path-like
        Where the report, JSON and figures go.
    """
    from .registry import CASES

    progress = progress or (lambda msg: None)
    names = list(names) or [name for name, case in CASES.items() if not case.by_name_only]
    unknown = [n for n in names if n not in CASES]
    if unknown:
        raise KeyError(f"unknown validation case(s) {unknown}; available: {', '.join(CASES)}")
    with output_lock(output_folder(out_dir)) as out:
        remove_stale_temporaries(out)
        return _run_cases(names, out, progress)


def _run_cases(names, out: Path, progress) -> list[CaseResult]:
    from .registry import CASES

    results = []
    for name in names:
        progress(f"validation case {name}: {CASES[name].title}")
        t0 = time.perf_counter()
        result = CASES[name].run(out)
        result.wall_time_s = time.perf_counter() - t0
        for c in result.checks:
            progress(f"  {c.quantity}: {c.computed:.6g} vs {c.reference:.6g} -> {'pass' if c.passed else 'FAIL'}")
        results.append(result)
    write_text(out / "report.md", _markdown(results))
    write_json(out / "validation.json", {
        "passed": all(r.passed for r in results),
        "cases": [{"name": r.name, "title": r.title, "passed": r.passed, "wall_time_s": r.wall_time_s,
                   "notes": r.notes, "figures": r.figures, "checks": [c.to_dict() for c in r.checks]}
                  for r in results],
    })
    return results
