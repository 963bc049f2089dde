"""JSON output written atomically."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from .files import open_atomic


def _plain(value):
    """Convert NumPy scalars/arrays to JSON types; refuse NaN and infinity."""
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, np.ndarray):
        return _plain(value.tolist())
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None  # JSON has no NaN; null says "no value" honestly
    return value


def write_json(path, data: dict) -> Path:
    """Write ``data`` as indented JSON via a temporary file and a rename."""
    path = Path(path)
    text = json.dumps(_plain(data), indent=2, allow_nan=False) + "\n"  # fails before a file is touched
    with open_atomic(path, "w", encoding="utf-8") as fh:
        fh.write(text)
    return path


#: what a stage of a run can be doing; a killed run leaves "running" behind
STAGE_STATUS = ("not run", "running", "finished", "failed", "interrupted")


class RunRecord:
    """The ``summary.json`` of a run, rewritten whenever one of its stages starts or ends.

    A run that is killed leaves the summary of the stage it was in, marked
    ``running``; the top-level ``converged`` is true only when every stage
    finished and converged, so a stale success never survives a later stage.

    Parameters
    ----------
    path : path-like
        The summary file.
    header : dict
        Entries written first (title, analysis type).
    stages : sequence of str
        The stages of the run, in order.
    """

    def __init__(self, path, header: dict, stages):
        self.path = Path(path)
        self.header = dict(header)
        self.stages = {name: {"status": "not run"} for name in stages}
        self.body: dict = {}

    @property
    def converged(self) -> bool:
        return all(s["status"] == "finished" and s.get("converged", False) for s in self.stages.values())

    @property
    def status(self) -> str:
        states = [s["status"] for s in self.stages.values()]
        for worst in ("failed", "interrupted", "running"):
            if worst in states:
                return worst
        return "finished"

    def write(self, body: dict | None = None) -> Path:
        """Write the summary: the header, ``body`` (the results so far), the stages and the outcome."""
        if body is not None:
            self.body = dict(body)
        # "run_status": an analysis may report a "status" of its own (why a path stopped)
        data = {**self.header, **self.body, "run_status": self.status, "converged": self.converged,
                "stages": self.stages}
        return write_json(self.path, data)

    def start(self, stage: str, body: dict | None = None) -> None:
        self.stages[stage] = {"status": "running"}
        self.write(body)

    def finish(self, stage: str, converged: bool, message: str | None = None, body: dict | None = None) -> None:
        entry = {"status": "finished", "converged": bool(converged)}
        if message:
            entry["message"] = message
        self.stages[stage] = entry
        self.write(body)

    def stop(self, status: str, message: str) -> None:
        """Mark the running stage(s) ``failed`` or ``interrupted`` with ``message`` and write."""
        if status not in ("failed", "interrupted"):
            raise ValueError(f"stop status must be 'failed' or 'interrupted', got {status!r}")
        running = [k for k, s in self.stages.items() if s["status"] == "running"]
        # between two stages the next one is the one that did not happen
        pending = [k for k, s in self.stages.items() if s["status"] == "not run"][:1]
        for k in running or pending or list(self.stages)[-1:]:
            self.stages[k] = {"status": status, "message": message}
        self.write()
