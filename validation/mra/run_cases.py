"""Run the MRA scenes of this folder and tabulate their summaries.

Each ``*.toml`` here is one case for :func:`shellform.analyses.form_finding.run_mra_case`; results go to
``results/<name>/`` (``hanging.vtu``, ``inverted.vtu``, ``summary.json``) and the table of
all cases to ``results/cases.md`` (cases not named on the command line from their last
``summary.json``).

Run:  python validation/mra/run_cases.py [scene.toml ...]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # many small BLAS calls: threads only add overhead

import json  # noqa: E402
import sys  # noqa: E402
import tomllib  # noqa: E402
from pathlib import Path  # noqa: E402

from shellform.io.files import output_folder, safe_name, write_text  # noqa: E402
from shellform.analyses.form_finding import run_mra_case  # noqa: E402

HERE = Path(__file__).resolve().parent


def case_folder(results: Path, params: dict, path) -> Path:
    """The results folder of a case: its name made a plain file name, so it stays in ``results``."""
    return results / safe_name(params.get("name", Path(path).stem))


def main(paths, results: Path = HERE / "results") -> list[dict]:
    results = output_folder(results)
    rows = []
    for path in paths:
        params = tomllib.loads(Path(path).read_text())
        out = case_folder(results, params, path)
        print(f"== {path}")
        s = run_mra_case(params, out, progress=lambda msg: None if msg.startswith("  ") else print(msg))
        rows.append(s)
        st = s["start"]
        saved = ""
        if "flat" in st:
            saved = (f"flat start {st['flat']['iterations']} it. / {st['flat']['wall_time_s']:.2f} s, "
                     f"{st['type']} start {st['iterations']} it. / {st['wall_time_s'] + st.get('preparation_s', 0):.2f} s")
        print(f"   converged {s['converged']}, {s['iterations']} iterations, max velocity {s['max_velocity']:.2e}, "
              f"max acceleration {s['max_acceleration']:.2e}, slack ropes {s['n_slack_ropes']}/{s['n_ropes']}, "
              f"rise {s['rise']:.3f} m, residual/weight {s['residual_over_weight']:.1e}, {s['wall_time_s']:.2f} s")
        if saved:
            print("   " + saved)
    # the table lists every case of this folder: those not run now from their last summary
    ran = {s["name"] for s in rows}
    for path in sorted(HERE.glob("*.toml")):
        name = tomllib.loads(path.read_text()).get("name", path.stem)
        saved = case_folder(results, {"name": name}, path) / "summary.json"
        if name not in ran and saved.exists():
            rows.append(json.loads(saved.read_text()))
    rows.sort(key=lambda s: s["name"])
    lines = ["| case | nodes | ropes | scheme | converged | iterations | max v [m/s] | max a [m/s^2] | slack | rise [m] "
             "| residual/weight | strain max (ropes > limit) | lengths min/mean/max [m] | length classes (within tol) | D.o.F / D.o.C | start comparison | time [s] |",
             "|" + "---|" * 17]
    for s in rows:
        L = s["rope_lengths"]
        h = s["hypostatic"]
        st = s["start"]
        cmp = "-"
        if "flat" in st:
            cmp = (f"flat {st['flat']['iterations']} it./{st['flat']['wall_time_s']:.2f} s vs {st['type']} "
                   f"{st['iterations']} it./{st['wall_time_s'] + st.get('preparation_s', 0):.2f} s")
        lines.append(
            f"| {s['name']} | {s['n_nodes']} | {s['n_ropes']} | {s['scheme']} | {s['converged']} | {s['iterations']} "
            f"| {s['max_velocity']:.1e} | {s['max_acceleration']:.1e} | {s['n_slack_ropes']} | {s['rise']:.3f} "
            f"| {s['residual_over_weight']:.1e} | {s['strain_max']:.1e} ({s['n_overstretched_ropes']}) "
            f"| {L['min']:.3f}/{L['mean']:.3f}/{L['max']:.3f} | {L['n_classes']} "
            f"| {h['dof']} / {h['doc']} | {cmp} | {s['wall_time_s']:.2f} |")
        if "length_control" in s:
            lc = s["length_control"]
            lines.append(f"|  ... length control ({lc['n_classes']} classes) | | | | {lc['converged']} | | | | | | | "
                         f"{lc['strain_max']:.1e} ({lc['n_overstretched_ropes']}) | conforming per round {lc['n_conforming_per_round']} of {s['n_ropes']} | | | | "
                         f"{lc['wall_time_s']:.2f} |")
    write_text(results / "cases.md", "\n".join(lines) + "\n")
    print("\n".join(lines))
    return rows


if __name__ == "__main__":
    main(sys.argv[1:] or sorted(HERE.glob("*.toml")))
