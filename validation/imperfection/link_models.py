"""Imperfection studies of the two link models against their exact maximum loads and Koiter's laws.

    python validation/imperfection/link_models.py [--out DIR] [--workers N]

Runs ``shellform study imperfection`` on the symmetric and the asymmetric link
model (``shellform.studies.link_models``) for its critical mode at amplitudes
from 1e-6 to 1e-2 of the strut length (the asymmetric model on both sides),
compares every knock-down factor with the exact one, fits the exponent of
``1 - kappa = C a^e`` over the amplitudes 1e-6 .. 1e-3 (three decades, where the
asymptotic law holds to well within 2 %) and writes ``link_models.json``,
``link_models.md`` and ``link_models.png`` (computed points on the exact curves).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # the checkout, whether installed or not

from shellform.io import write_json  # noqa: E402
from shellform.io.files import write_text  # noqa: E402
from shellform.io.study_plots import KnockdownCurve, plot_knockdown  # noqa: E402
from shellform.studies import StudyOptions, run_imperfection_study  # noqa: E402
from shellform.studies.link_models import critical_load, exact_knockdown, link_scene  # noqa: E402
from shellform.studies.statistics import knockdown_exponent  # noqa: E402

STUDY = """shapes = "modes"
modes = 1
signs = "{signs}"
relative_to = "absolute"
amplitude_min = 1e-6
amplitude_max = 1e-2
amplitude_count = 9
"""
#: the amplitudes the exponent is fitted over, and what it must be
FIT_RANGE = (1e-6, 1e-3)
EXPONENT = {"symmetric": 2.0 / 3.0, "asymmetric": 0.5}
TOLERANCE = {"knockdown": 1e-3, "exponent": 0.02}


def run(out: Path, workers: int) -> dict:
    report = {}
    for kind, signs, dangerous in (("symmetric", "positive", "mode_1 +"), ("asymmetric", "both", "mode_1 -")):
        scene = out / f"{kind}.toml"
        write_text(scene, link_scene(kind, STUDY.format(signs=signs)))
        summary = run_imperfection_study(scene, out / kind, StudyOptions(workers=workers),
                                         lambda msg: print(msg, file=sys.stderr))
        curves = {}
        for name, curve in summary["knockdown"].items():
            sign = -1.0 if name.endswith("-") else 1.0
            a = np.asarray(curve["amplitude"])
            kappa = np.asarray(curve["knockdown"])
            exact = np.array([exact_knockdown(kind, sign * x) for x in a])
            curves[name] = {"amplitude": a.tolist(), "knockdown": kappa.tolist(), "exact": exact.tolist(),
                            "largest_error": float(np.abs(kappa - exact).max())}
        d = curves[dangerous]
        a, kappa = np.asarray(d["amplitude"]), np.asarray(d["knockdown"])
        within = (a >= FIT_RANGE[0] * (1 - 1e-9)) & (a <= FIT_RANGE[1] * (1 + 1e-9))
        fit = knockdown_exponent(a[within], kappa[within])
        exponent_error = abs(fit["exponent"] / EXPONENT[kind] - 1.0)
        report[kind] = {
            "lam_cr_perfect": summary["perfect"]["lam_cr"], "lam_c_exact": critical_load(kind),
            "perfect_kind": summary["perfect"]["kind"], "curves": curves,
            "fit_range": FIT_RANGE, "fit": fit, "expected_exponent": EXPONENT[kind],
            "exponent_relative_error": exponent_error,
            "passed": bool(d["largest_error"] <= TOLERANCE["knockdown"] and exponent_error <= TOLERANCE["exponent"]
                           and len(a) >= 5 and a.max() / a.min() >= 100.0),
            "wall_time_s": summary["wall_time_s"],
        }
    return report


def figure(out: Path, report: dict) -> None:
    curves = []
    for kind, r in report.items():
        for name, c in r["curves"].items():
            sign = -1.0 if name.endswith("-") else 1.0
            fine = np.geomspace(min(c["amplitude"]), max(c["amplitude"]), 60)
            curves.append(KnockdownCurve(f"{kind}, {name}", c["amplitude"], c["knockdown"],
                                         (fine, [exact_knockdown(kind, sign * x) for x in fine])))
    plot_knockdown(out / "link_models.png", curves, "amplitude a / L [-]", "perfect: bifurcation",
                   "Link models: computed knock-down (points) on the exact curves (grey)")


def markdown(report: dict) -> str:
    lines = ["# Link models: knock-down against the exact maximum loads", "",
             "| model | curve | amplitudes | largest abs. error of kappa | fitted exponent (1e-6..1e-3) | "
             "expected | passed |", "|---|---|---|---|---|---|---|"]
    for kind, r in report.items():
        for name, c in r["curves"].items():
            fit = f"{r['fit']['exponent']:.4f}" if name.endswith("-" if kind == "asymmetric" else "+") else "—"
            lines.append(f"| {kind} | {name} | {min(c['amplitude']):.0e}..{max(c['amplitude']):.0e} | "
                         f"{c['largest_error']:.2e} | {fit} | {r['expected_exponent']:.4f} | {r['passed']} |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=str(Path(__file__).with_name("results")))
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    report = run(out, args.workers)
    write_json(out / "link_models.json", report)
    write_text(out / "link_models.md", markdown(report))
    figure(out, report)
    print(markdown(report))
    print(json.dumps({k: {"fit": v["fit"], "passed": v["passed"]} for k, v in report.items()}, indent=1))
    return 0 if all(r["passed"] for r in report.values()) else 1


if __name__ == "__main__":
    sys.exit(main())
