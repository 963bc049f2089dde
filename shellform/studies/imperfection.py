"""An imperfection-sensitivity study of a scene: knock-down curves and fractiles of the critical load factor.

``shellform study imperfection SCENE --out DIR`` (see :mod:`shellform.studies`):

1. the perfect structure is traced to its first critical point (its
   critical load factor ``lam_cr,perfect``), where its buckling modes are
   taken (:mod:`~shellform.studies.shapes`); kept in ``perfect.json`` and
   ``perfect.npz`` so that a resumed study takes the same shapes;
2. every sample (shape, sign, amplitude) is an imperfect structure traced
   to its first critical point (:mod:`~shellform.studies.sample`), on the
   runner of :mod:`shellform.studies.runner` (this process, a process pool, Dask);
   each finished sample is written to ``samples/sample_NNNNN.json`` and the
   table ``study.csv`` is rewritten as samples finish;
3. the knock-down curves (``knockdown.png``), the distribution of random
   samples (``distribution.png``, ``statistics.csv``), the figures in
   ``study.json``, and the worst sample's whole path in ``worst/`` like any
   continuation result.

Run again into the same folder, a study keeps every sample whose record
names the same scene and settings and runs the rest; a failed sample is a
row with its message and is run again next time.
"""

from __future__ import annotations

import json
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import SceneError, ShellformError
from ..io import write_json, write_mode
from ..io.mesh import evaluated_with
from ..fingerprint import digest
from ..io.checkpoint import load_checkpoint, save_checkpoint
from ..io.files import output_folder, output_lock
from ..io.table import write_csv
from .post_buckling import post_buckling
from .runner import Runner
from . import shapes as sh
from .sample import critical_record, imperfect_model, run_sample, trace_to_instability
from .settings import StudySettings, study_settings
from .statistics import fractile, knockdown_exponent, moments

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

Progress = Callable[[str], None]

COLUMNS = ("sample", "shape", "sign", "amplitude", "movement", "status", "event", "lam_cr", "knockdown",
           "lam_reached", "steps", "wall_time_s", "message")
UNITS = {"amplitude": "-", "movement": "m", "lam_cr": "-", "knockdown": "-", "lam_reached": "-", "steps": "-",
         "sign": "-", "wall_time_s": "s"}


class StudyError(ShellformError):
    """A study that cannot go on: the perfect structure has no critical point, or its path failed."""


@dataclass
class StudyOptions:
    """Where the samples run (:class:`~shellform.studies.runner.Runner`) and whether finished ones are run again."""

    workers: int = 2
    scheduler: str | None = None
    #: compute the perfect structure and every sample again, also what a previous study into the folder finished
    rerun: bool = False
    runner: Runner = field(init=False)

    def __post_init__(self):
        self.runner = Runner(self.workers, self.scheduler)


@dataclass(frozen=True)
class Perfect:
    """The perfect structure at its first critical point, and the study's unit shapes."""

    lam_cr: float
    kind: str
    reference_length: float
    #: (k, n_nodes, 3) buckling modes (none for a random field)
    modes: np.ndarray
    eigenvalues: np.ndarray
    q: np.ndarray
    #: at a bifurcation, the way of its secondary paths and Koiter's class (:mod:`.post_buckling`)
    post_buckling: dict = field(default_factory=dict)


def _died(why: str) -> dict:
    return {"status": "failed", "event": "none", "lam_cr": None, "message": f"the worker running the sample died: {why}"}


def _settings_record(s: StudySettings) -> dict:
    return {"shapes": s.shapes, "modes": s.modes, "seed": s.seed, "correlation_length": s.correlation_length,
            "relative_to": s.relative_to, "max_step_angle": s.max_step_angle}


def _perfect(scene: dict, settings: StudySettings, out: Path, fingerprint: str, progress: Progress,
             rerun: bool = False) -> Perfect:
    """The perfect structure's critical point and modes, from ``perfect.npz`` when it is of this study
    (and not ``rerun``: then everything is computed again)."""
    model = imperfect_model(scene, None)
    k = settings.modes if settings.shapes != "random_field" else 0
    key = digest(fingerprint, k)
    saved = None if rerun else load_checkpoint(out / "perfect.npz")
    if saved is not None and str(saved.get("key")) == key:
        progress(f"perfect structure: from {out / 'perfect.npz'}")
        return Perfect(float(saved["lam_cr"]), str(saved["kind"]), float(saved["reference_length"]),
                       saved["modes"], saved["eigenvalues"], saved["q"], json.loads(str(saved["post_buckling"])))
    t0 = time.perf_counter()
    res = trace_to_instability(scene, model, settings.max_step_angle)
    record = critical_record(res)
    if record["event"] == "none":
        c = scene["analysis"]["continuation"]
        if record["status"] == "failed":
            raise StudyError(f"the path of the perfect structure failed before a critical point: {res.message}")
        raise SceneError("analysis.continuation.parameter_max", f"the perfect structure keeps its stability up to "
                         f"load factor {record['lam_reached']:.6g} ({res.message}); a study needs its critical "
                         f"point: raise parameter_max (now {c['parameter_max']}), max_displacement or max_steps")
    event = res.events[0]
    length = sh.reference_length(model.structure, settings.relative_to)
    with evaluated_with(model.system, event.history):  # a rod state's tangent with the frames it was found with
        values, modes = (sh.mode_shapes(model.system, event.q, k) if k else
                         (np.zeros(0), np.zeros((0, model.structure.n_nodes, 3))))
    after = post_buckling(scene, settings.max_step_angle) if event.kind == "bifurcation" else {}
    progress(f"perfect structure: {event.kind} point at load factor {event.lam:.6g}"
             + (f", {after['class']} (secondary path {after['+']} on the + side, {after['-']} on the - side)"
                if after else "")
             + f" ({time.perf_counter() - t0:.2f} s); reference length ({settings.relative_to}) {length:.6g} m")
    perfect = Perfect(float(event.lam), event.kind, length, modes, values, event.q, after)
    n_dof = model.structure.n_dof
    files = []
    for i, shape in enumerate(modes):
        full = np.zeros(n_dof)
        full[: shape.size] = shape.ravel()
        files.append(write_mode(out / f"mode_{i + 1}.vtu", model.system, event.q, full, event.lam,
                                history=event.history).name)
    save_checkpoint(out / "perfect.npz", key=key, lam_cr=perfect.lam_cr, kind=perfect.kind,
                    reference_length=length, modes=modes, eigenvalues=values, q=event.q,
                    post_buckling=json.dumps(after))
    write_json(out / "perfect.json", {"lam_cr": perfect.lam_cr, "kind": perfect.kind, "post_buckling": after,
                                      "steps": res.steps,
                                      "reference_length_m": length, "relative_to": settings.relative_to,
                                      "mode_eigenvalues_N_per_m": values.tolist(), "mode_files": files})
    return perfect


class Shapes:
    """The node movement of every sample (unit shapes made once)."""

    def __init__(self, settings: StudySettings, perfect: Perfect, structure):
        self.settings, self.perfect = settings, perfect
        self.free = sh.free_node_mask(structure)
        self.factor = (sh.field_factor(structure.nodes, settings.correlation_length)
                       if settings.shapes == "random_field" else None)

    def delta(self, s: sh.Sample) -> np.ndarray:
        if s.draw >= 0:
            unit = sh.random_shape(self.settings, s.draw, self.perfect.modes, self.factor, self.free)
        else:
            unit = self.perfect.modes[int(s.shape.split("_")[1]) - 1]
        return (s.sign * s.amplitude * self.perfect.reference_length) * unit


#: seconds between two rewrites of ``study.csv`` while samples finish (each is a whole file, flushed to disk:
#: rewritten after every sample of a 200-sample study they took a third of its time on 2 workers)
TABLE_INTERVAL = 1.0


class StudyTable:
    """The rows of a study so far, rewritten to ``study.csv`` (atomically) as samples finish, at most every
    :data:`TABLE_INTERVAL` seconds, and when :meth:`write` is called."""

    def __init__(self, out: Path, perfect: Perfect):
        self.out, self.perfect = out, perfect
        self.rows: dict[int, dict] = {}
        self._written = -np.inf

    def add(self, sample: sh.Sample, record: dict) -> dict:
        lam = record.get("lam_cr")
        row = {"sample": sample.name, "shape": sample.shape, "sign": sample.sign, "amplitude": sample.amplitude,
               "movement": sample.amplitude * self.perfect.reference_length, "status": record["status"],
               "event": record.get("event", "none"), "lam_cr": lam,
               "knockdown": lam / self.perfect.lam_cr if lam is not None else None,
               "lam_reached": record.get("lam_reached"), "steps": record.get("steps"),
               "wall_time_s": record.get("wall_time_s"), "message": record.get("message", "")}
        self.rows[sample.index] = row
        if time.perf_counter() - self._written >= TABLE_INTERVAL:
            self.write()
        return row

    @property
    def ordered(self) -> list[dict]:
        return [self.rows[i] for i in sorted(self.rows)]

    def write(self) -> None:
        rows = self.ordered
        write_csv(self.out / "study.csv", {c: ["" if r[c] is None else r[c] for r in rows] for c in COLUMNS},
                  COLUMNS, units=UNITS)
        self._written = time.perf_counter()


def _fingerprint(raw: dict, base_dir: str, settings: StudySettings) -> str:
    """The scene without its ``[study]`` and the settings that change a sample's answer (not the amplitudes,
    counts or fractile: a sample is named by its own amplitude and draw)."""
    scene = {k: v for k, v in raw.items() if k != "study"}
    return digest({"scene": scene, "base_dir": base_dir}, _settings_record(settings))


def _sample_key(fingerprint: str, s: sh.Sample) -> str:
    return digest(fingerprint, s.shape, s.sign, s.amplitude, s.draw)


def _kept(folder: Path, key: str) -> dict | None:
    try:
        record = json.loads(folder.read_text())
    except (OSError, ValueError):
        return None
    if isinstance(record, dict) and record.get("key") == key and record.get("status") == "finished":
        return record
    return None


def run_imperfection_study(scene_path, out_dir, options: StudyOptions | None = None,
                           progress: Progress | None = None) -> dict:
    """Run the imperfection study a scene's ``[study]`` describes; returns the study's summary.

    Raises
    ------
    SceneError
        A key of the scene that does not fit a study (before any sample runs),
        or a perfect structure without a critical point in the traced range.
    """
    from ..scene import load_scene

    opts = options or StudyOptions()
    progress = progress or (lambda msg: None)
    scene_path = Path(scene_path)
    scene = load_scene(scene_path)
    settings = study_settings(scene)
    raw = tomllib.loads(scene_path.read_text())
    base_dir = str(scene_path.resolve().parent)
    fingerprint = _fingerprint(raw, base_dir, settings)
    t0 = time.perf_counter()
    with output_lock(output_folder(out_dir)) as out:
        perfect = _perfect(scene, settings, out, fingerprint, progress, opts.rerun)
        structure = imperfect_model(scene, None).structure
        shapes = Shapes(settings, perfect, structure)
        samples = sh.study_samples(settings)
        table = StudyTable(out, perfect)
        records = output_folder(out / "samples")
        todo, kept = [], 0
        for s in samples:
            key = _sample_key(fingerprint, s)
            record = None if opts.rerun else _kept(records / f"{s.name}.json", key)
            if record is not None:
                table.add(s, record)
                kept += 1
            else:
                todo.append(s)
        progress(f"study: {len(samples)} samples of {scene_path.name} ({settings.shapes}), {kept} finished before, "
                 f"{len(todo)} to run {opts.runner.where(len(todo))}")
        table.write()
        tasks = [(s, (scene, shapes.delta(s), settings.max_step_angle)) for s in todo]
        try:
            for s, record in opts.runner.run(run_sample, tasks, _died):
                write_json(records / f"{s.name}.json", {**record, "key": _sample_key(fingerprint, s),
                                                       "shape": s.shape, "sign": s.sign, "amplitude": s.amplitude,
                                                       "draw": s.draw})
                row = table.add(s, record)
                lam = f"lam_cr {row['lam_cr']:.6g} ({row['event']}), knock-down {row['knockdown']:.4f}" \
                    if row["lam_cr"] is not None else (f"no critical point up to {row['lam_reached']}"
                                                       if row["status"] == "finished" else row["message"])
                progress(f"  {s.name} {s.shape} sign {s.sign:+d} amplitude {s.amplitude:.4g}: {row['status']}, "
                         f"{lam}")
        finally:
            table.write()  # every finished sample in the table, also when the run is interrupted
        summary = summarise(table.ordered, settings, perfect, scene)
        summary["kept"] = kept
        summary["files"] = _figures(out, summary, table.ordered, settings, perfect, scene, progress)
        summary["worst"] = _worst(out, scene, settings, shapes, samples, table, fingerprint, progress)
        if summary["worst"]:
            summary["files"].append("worst/")
        summary["wall_time_s"] = time.perf_counter() - t0
        write_json(out / "study.json", summary)
        return summary


def summarise(rows: list[dict], settings: StudySettings, perfect: Perfect, scene: dict) -> dict:
    """The figures of a study's rows: knock-down curves and exponents per shape, statistics per amplitude."""
    finished = [r for r in rows if r["status"] == "finished"]
    summary = {
        "analysis": "imperfection_study", "title": scene["title"], "settings": _settings_record(settings),
        "amplitudes": list(settings.amplitudes), "fractile": settings.fractile, "confidence": settings.confidence,
        "perfect": {"lam_cr": perfect.lam_cr, "kind": perfect.kind, "post_buckling": perfect.post_buckling,
                    "mode_eigenvalues_N_per_m": perfect.eigenvalues.tolist()},
        "reference_length_m": perfect.reference_length, "samples": len(rows), "finished": len(finished),
        "failed": len(rows) - len(finished), "stable_over_range": sum(r["lam_cr"] is None for r in finished),
        "warnings": _jumps(finished, perfect.post_buckling),
        "units": {"lam_cr": "-", "knockdown": "-", "amplitude": "multiple of the reference length",
                  "reference_length_m": "m", "wall_time_s": "s"},
    }
    if not settings.random:
        curves = {}
        for r in finished:
            if r["knockdown"] is not None:
                curves.setdefault(f"{r['shape']} {'+' if r['sign'] > 0 else '-'}", []).append(
                    (r["amplitude"], r["knockdown"]))
        summary["knockdown"] = {name: {"amplitude": [p[0] for p in pts], "knockdown": [p[1] for p in pts],
                                       "fit": knockdown_exponent(*zip(*pts)) if len(pts) > 1 else None}
                                for name, pts in curves.items()}
        return summary
    stats = []
    for amplitude in settings.amplitudes:
        at = [r for r in rows if r["amplitude"] == amplitude]
        done = [r for r in at if r["status"] == "finished"]
        lam = [r["lam_cr"] if r["lam_cr"] is not None else np.inf for r in done]
        frac = fractile(lam, settings.fractile, settings.confidence)
        kappa = {k: (v / perfect.lam_cr if isinstance(v, float) else None)
                 for k, v in frac.items() if k in ("estimate", "lower", "upper", "lower_bound")}
        stats.append({"amplitude": amplitude, "samples": len(at), "finished": len(done),
                      "stable_over_range": sum(r["lam_cr"] is None for r in done),
                      "lam_cr": moments([v for v in lam if np.isfinite(v)]), "fractile": frac,
                      "fractile_knockdown": kappa})
    summary["statistics"] = stats
    return summary


def _jumps(rows: list[dict], after: dict) -> list[str]:
    """A bifurcation above the perfect structure's critical load where nothing explains it: a jump to another branch?

    Above a stable or asymmetric bifurcation (a secondary path that rises)
    imperfect structures are expected to lose stability later than the perfect one.
    """
    if "rises" in (after.get("+"), after.get("-")):
        return []
    jumped = [r["sample"] for r in rows if r["event"] == "bifurcation" and (r["knockdown"] or 0.0) > 1.0 + 1e-6]
    if not jumped:
        return []
    return [f"{len(jumped)} sample(s) lost stability at a bifurcation above the perfect structure's critical load "
            f"({', '.join(jumped[:5])}{', ...' if len(jumped) > 5 else ''}), although no secondary path of the "
            "perfect structure rises: their paths may have jumped to another branch; a smaller "
            "analysis.continuation.initial_increment keeps them on theirs"]


def _figures(out: Path, summary: dict, rows: list[dict], settings: StudySettings, perfect: Perfect, scene: dict,
             progress: Progress) -> list[str]:
    """``knockdown.png``, and for random shapes ``statistics.csv`` and ``distribution.png``; a plot that fails is noted."""
    from ..io.study_plots import KnockdownCurve, plot_distribution, plot_knockdown

    files = ["study.csv", "study.json", "perfect.json", "perfect.npz"]
    files += [f"mode_{i + 1}.vtu" for i in range(len(perfect.modes))]
    xlabel = ("amplitude [m]" if settings.relative_to == "absolute" else
              f"amplitude / {settings.relative_to.replace('_', ' ')} ({perfect.reference_length:.4g} m) [-]")
    marked = f"perfect: {perfect.kind} at lam_cr = {perfect.lam_cr:.5g}"
    plots = []
    if not settings.random:
        curves = [KnockdownCurve(name, c["amplitude"], c["knockdown"]) for name, c in summary["knockdown"].items()]
        plots.append(("knockdown.png", lambda: plot_knockdown(out / "knockdown.png", curves, xlabel, marked,
                                                              scene["title"])))
    else:
        stats = summary["statistics"]
        p = settings.fractile
        table = {"amplitude": [s["amplitude"] for s in stats], "samples": [s["samples"] for s in stats],
                 "finished": [s["finished"] for s in stats], "stable_over_range": [s["stable_over_range"] for s in stats]}
        for name, pick in (("mean", lambda s: s["lam_cr"]["mean"]), ("std", lambda s: s["lam_cr"]["std"]),
                           ("min", lambda s: s["lam_cr"]["min"]), ("fractile", lambda s: s["fractile"]["estimate"]),
                           ("fractile_lower", lambda s: s["fractile"]["lower"]),
                           ("fractile_upper", lambda s: s["fractile"]["upper"]),
                           ("fractile_lower_bound", lambda s: s["fractile"]["lower_bound"])):
            table[f"lam_cr_{name}"] = ["" if pick(s) is None else pick(s) for s in stats]
        units = {c: "-" for c in table}
        write_csv(out / "statistics.csv", table, units=units)
        files.append("statistics.csv")
        curves = [KnockdownCurve(label, [s["amplitude"] for s in stats],
                                 [np.nan if pick(s) is None else pick(s) / perfect.lam_cr for s in stats])
                  for label, pick in (("mean", lambda s: s["lam_cr"]["mean"]),
                                      (f"{p:g}-fractile", lambda s: s["fractile"]["estimate"]),
                                      ("smallest", lambda s: s["lam_cr"]["min"]))]
        plots.append(("knockdown.png", lambda: plot_knockdown(out / "knockdown.png", curves, xlabel, marked,
                                                              scene["title"])))
        last = stats[-1]
        at = [r for r in rows if r["amplitude"] == last["amplitude"] and r["status"] == "finished"]
        kappa = [r["knockdown"] for r in at if r["knockdown"] is not None]
        marks = {"p": p, "confidence": settings.confidence, **last["fractile_knockdown"]}
        plots.append(("distribution.png", lambda: plot_distribution(
            out / "distribution.png", kappa, last["stable_over_range"], marks,
            f"{scene['title']}: amplitude {last['amplitude']:g}")))
    for name, draw in plots:
        try:
            files.append(draw().name)
        except Exception as exc:  # noqa: BLE001 (the table and figures are written; a plot only pictures them)
            summary.setdefault("warnings", []).append(f"plot {name} not drawn: {type(exc).__name__}: {exc}")
            progress(summary["warnings"][-1])
    return files


def _worst(out: Path, scene: dict, settings: StudySettings, shapes: Shapes, samples: list, table: StudyTable,
           fingerprint: str, progress: Progress) -> dict | None:
    """Trace the whole path of the sample with the lowest critical load factor into ``worst/``.

    A ``worst/`` of the same sample, written by an earlier run of the study, is kept.
    """
    from ..analyses.continuation import trace_model
    from ..progress import Status, indented

    rows = [(r["lam_cr"], i) for i, r in table.rows.items() if r["lam_cr"] is not None]
    if not rows:
        return None
    _, index = min(rows)
    s = samples[index]
    folder = output_folder(out / "worst")
    worst = {"sample": s.name, "shape": s.shape, "sign": s.sign, "amplitude": s.amplitude,
             "lam_cr": table.rows[index]["lam_cr"], "knockdown": table.rows[index]["knockdown"],
             "key": _sample_key(fingerprint, s)}
    try:
        if json.loads((folder / "summary.json").read_text()).get("sample", {}).get("key") == worst["key"]:
            progress(f"worst sample {s.name}: its path in {folder} from before")
            return worst
    except (OSError, ValueError, AttributeError):
        pass
    progress(f"worst sample {s.name} ({s.shape}, sign {s.sign:+d}, amplitude {s.amplitude:g}): its path into "
             f"{folder}")
    model = imperfect_model(scene, shapes.delta(s))
    lines = lambda msg: None if isinstance(msg, Status) else progress(msg)  # noqa: E731 (no step lines)
    summary = trace_model(scene, model, folder, indented(lines), resume=False,
                          max_angle_deg=settings.max_step_angle)
    write_json(folder / "summary.json", {"title": scene["title"], "sample": worst, **summary})
    return worst
