"""The validation cases ``shellform validate`` knows."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from . import cases_core, cases_hemisphere, cases_mra, cases_rods


@dataclass(frozen=True)
class Case:
    title: str
    run: Callable
    #: run only when named: a case of half an hour or more is not part of "every case"
    by_name_only: bool = False


CASES: dict[str, Case] = {
    "catenary": Case("hanging chain vs analytic catenary", cases_core.case_catenary),
    "von_mises": Case("von Mises truss limit points vs analytic", cases_core.case_von_mises),
    "rods": Case("discrete elastic rods: elastica, Euler and Greenhill buckling", cases_rods.case_rods),
    "mra": Case("MRA form finding: catenary, 9 x 4 net, membrane limit", cases_mra.case_mra),
    "hemisphere": Case("hemispherical gridshell snapping thresholds, n = 5..11, modes I and II (minutes)",
                       cases_hemisphere.case_hemisphere),
    "hemisphere_fig7": Case("hemispherical gridshell, the paper's Fig. 7: first snap and maximum force against n "
                            "= 5..29 (about half an hour on 2 cores; n = 39, 49 through ns)",
                            cases_hemisphere.case_hemisphere_fig7, by_name_only=True),
}
