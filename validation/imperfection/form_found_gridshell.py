"""Imperfection sensitivity of the form-found timber gridshell: knock-down for its lowest three modes.

    python validation/imperfection/form_found_gridshell.py [--out DIR] [--workers N]

Runs ``shellform study imperfection`` on ``form_found_gridshell.toml`` (the
laths of ``scenes/form_found_gridshell.toml`` on the MRA shape of
``meshes/form_found_gridshell.obj``; three modes, both signs, five amplitudes)
and writes ``form_found_gridshell.json``, ``form_found_gridshell.md`` and
``form_found_gridshell_knockdown.png``: the perfect shell's critical point with
the way its secondary paths go (Koiter's class), and the knock-down factor of
every mode, sign and amplitude.
"""

from __future__ import annotations

import argparse
import shutil
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # the checkout, whether installed or not

from shellform.io import write_json  # noqa: E402
from shellform.io.files import write_text  # noqa: E402
from shellform.studies import StudyOptions, run_imperfection_study  # noqa: E402

from report import knockdown_table  # noqa: E402

HERE = Path(__file__).resolve().parent


def log(msg) -> None:
    print(msg, file=sys.stderr, flush=True)


def markdown(study: dict) -> str:
    p = study["perfect"]
    after = p.get("post_buckling") or {}
    lines = ["# Form-found timber gridshell: imperfection sensitivity", "",
             f"Perfect shell: {p['kind']} point at load factor {p['lam_cr']:.6g} (x the laths' weight and 5 kg "
             "of cladding per node)."]
    if after:
        lines += ["", f"Its secondary paths: {after['+']} on the + side, {after['-']} on the - side: "
                  f"**{after['class']}** bifurcation. Mode eigenvalues at the critical point "
                  f"[N/m]: {', '.join(f'{v:.4g}' for v in p['mode_eigenvalues_N_per_m'])}."]
    lines += ["", "## Knock-down lam_cr / lam_cr,perfect for the lowest three modes", ""]
    lines += knockdown_table(study)
    lines += ["", f"{study['finished']} of {study['samples']} samples finished, {study['failed']} failed; "
              f"wall time {study['wall_time_s']:.1f} s."]
    if study.get("warnings"):
        lines += [""] + [f"Warning: {w}" for w in study["warnings"]]
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=str(HERE / "results"))
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args(argv)
    out = Path(args.out)
    study = run_imperfection_study(HERE / "form_found_gridshell.toml", out / "gridshell_modes",
                                   StudyOptions(workers=args.workers, rerun=True), log)
    write_json(out / "form_found_gridshell.json", study)
    text = markdown(study)
    write_text(out / "form_found_gridshell.md", text)
    shutil.copyfile(out / "gridshell_modes" / "knockdown.png", out / "form_found_gridshell_knockdown.png")
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
