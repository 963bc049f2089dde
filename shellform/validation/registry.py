"""The validation cases ``shellform validate`` knows."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from . import cases_core


@dataclass(frozen=True)
class Case:
    title: str
    run: Callable


CASES: dict[str, Case] = {
    "catenary": Case("hanging chain vs analytic catenary", cases_core.case_catenary),
    "von_mises": Case("von Mises truss limit points vs analytic", cases_core.case_von_mises),
}
