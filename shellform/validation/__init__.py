"""Validation cases: computed results against published or analytic values.

``run_validation(names, out_dir)`` runs the registered cases and writes
``report.md`` (tables, figures, pass/fail) and ``validation.json``.
"""

from .report import Check, CaseResult, run_validation
from .registry import CASES

__all__ = ["Check", "CaseResult", "CASES", "run_validation"]
