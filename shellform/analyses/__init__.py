"""From a validated scene to results on disk: one runner per analysis.

Every runner returns a JSON-ready summary (``run_scene`` writes it to
``summary.json``, also when the analysis did not converge) and writes its
files through :mod:`shellform.io`. ``summary.json`` is written as the run
starts and as each of its stages starts and ends (``stages``,
``run_status``), so a run killed half-way never leaves a summary claiming
success. One run at a time holds an output folder. Long analyses keep a
checkpoint in the output folder and continue from it with ``resume=True``;
a checkpoint of another model or other settings is refused.

One module per analysis type: ``static``, ``continuation``, ``dynamics``,
``indentation``, ``form_finding`` (MRA) and ``form_and_buckle``; ``common``
holds what they share. The CLI, sweeps, validation cases and the Python API
all run scenes through :func:`run_scene`.
"""

from __future__ import annotations

import time

from ..errors import CheckpointMismatch
from ..io.files import output_folder, output_lock, remove_stale_temporaries, write_bytes
from ..io.summary import RunRecord
from ..io.units import units_block
from ..io.log import RunLog
from ..progress import Progress, quiet, tee
from .continuation import PathFiles, run_continuation, run_continuation_case
from .dynamics import run_dynamics
from .form_and_buckle import run_form_and_buckle
from .form_finding import run_form_finding
from .indentation import run_indentation
from .static import run_static

__all__ = ["ANALYSES", "STAGES", "run_scene", "run_continuation_case", "PathFiles"]

ANALYSES = {"static": run_static, "continuation": run_continuation, "dynamics": run_dynamics,
            "mra": run_form_finding, "form_and_buckle": run_form_and_buckle, "indentation": run_indentation}

#: the stages of each analysis, in order; a runner of more than one reports them itself
STAGES = {"static": ("static",), "continuation": ("continuation",), "dynamics": ("time_stepping",),
          "mra": ("form_finding",), "form_and_buckle": ("form_finding", "buckling"),
          "indentation": ("indentation",)}


def run_scene(scene: dict, out_dir, progress: Progress | None = None, resume: bool = False) -> dict:
    """Run a validated scene and write ``summary.json`` and its result files to ``out_dir``.

    The summary is written when the run starts (``run_status = "running"``), as
    each stage starts and ends, and at the end, also when the analysis does
    not converge or fails (with ``converged = false`` and the message), so
    the summary of a run that was killed never claims success. Its
    ``stages`` say how far the run got; ``converged`` is true only when every
    stage finished and converged. ``resume`` continues an interrupted
    continuation, relaxation or time stepping from the checkpoint in
    ``out_dir``.

    The output folder is locked for the run: a second run into it is refused.
    Every progress message is also appended to ``run.log`` there.

    Raises
    ------
    OutputError
        ``out_dir`` is a file, or another run holds it.
    """
    progress = progress or quiet
    kind = scene["analysis"]["type"]
    stages = STAGES[kind]
    with output_lock(output_folder(out_dir)) as out, RunLog(out / "run.log") as log:
        remove_stale_temporaries(out)  # of a run killed while writing: no one else writes here now
        progress = tee(log, progress)
        t0 = time.perf_counter()
        record = RunRecord(out / "summary.json", {"title": scene["title"], "analysis": kind}, stages)
        last = out / "summary.json"
        previous = last.read_bytes() if last.is_file() and not last.is_symlink() else None
        if len(stages) == 1:
            record.start(stages[0])
        else:
            record.write()
        try:
            if len(stages) == 1:
                summary = ANALYSES[kind](scene, out, progress, resume)
                record.finish(stages[0], bool(summary.get("converged", False)), summary.get("message"))
            else:
                summary = ANALYSES[kind](scene, out, progress, resume, record=record)
        except CheckpointMismatch as exc:
            # refused before anything was computed: the folder stays as the last run left it
            if previous is not None:
                write_bytes(out / "summary.json", previous)
                log.discard()
            else:
                record.stop("failed", str(exc))
            raise
        except KeyboardInterrupt:
            record.stop("interrupted", "interrupted; `shellform run ... --resume` continues from the last checkpoint")
            raise
        except BaseException as exc:
            record.stop("failed", f"{type(exc).__name__}: {exc}")
            raise
        summary = {"title": scene["title"], **summary}
        summary["wall_time_s"] = time.perf_counter() - t0
        summary["units"] = units_block()
        record.write(summary)
        # the log keeps what the screen shows at the end of a run
        for note in summary.get("warnings", []):
            log(f"warning: {note}")
        return {**summary, "run_status": record.status, "converged": record.converged, "stages": record.stages}
