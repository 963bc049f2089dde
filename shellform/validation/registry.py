"""The validation cases ``shellform validate`` knows."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from . import cases_core, cases_hemisphere, cases_mra, cases_rods


@dataclass(frozen=True)
class Case:
    title: str
    run: Callable


CASES: dict[str, Case] = {
    "catenary": Case("hanging chain vs analytic catenary", cases_core.case_catenary),
    "von_mises": Case("von Mises truss limit points vs analytic", cases_core.case_von_mises),
    "rods": Case("discrete elastic rods: elastica, Euler and Greenhill buckling", cases_rods.case_rods),
    "mra": Case("MRA form finding: catenary, 9 x 4 net, membrane limit", cases_mra.case_mra),
    "hemisphere": Case("hemispherical gridshell snapping thresholds, n = 5..11, modes I and II (minutes)",
                       cases_hemisphere.case_hemisphere),
}
