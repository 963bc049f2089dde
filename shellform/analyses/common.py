"""What every analysis runner shares: the progress type, model sizes, plots and the final state's files."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np

from .. import scene as scenes
from ..io import write_series, write_state

from ..progress import Progress


def model_sizes(structure, system) -> dict:
    return {
        "n_nodes": structure.n_nodes,
        "n_members": int(sum(g.n_members for g in structure.groups)),
        "n_dof": structure.n_dof,
        "n_free_dof": system.n_free,
        "effects": [e.name for e in system.effects],
    }


def series_time(*candidates: tuple[str, object]) -> tuple[str, np.ndarray]:
    """The first candidate ``(name, values)`` that increases from state to state.

    A time series is ordered by its time, so a load factor that turns back at
    a limit point cannot be one: the next candidate (an arc length, the step
    number) takes its place. The last candidate is used whatever it does.
    """
    for name, values in candidates:
        v = np.asarray(values, dtype=float)
        if v.size < 2 or np.all(np.diff(v) > 0):
            break
    return name, v


def plot_or_note(path: Path, draw: Callable[[], Path], files: list, notes: list) -> None:
    """Draw a plot (``draw()`` writes ``path``); a plot that fails is noted, not raised.

    A plot only pictures results already on disk; failing the run over it,
    after the analysis, would lose the summary instead.
    """
    try:
        files.append(draw().name)
    except Exception as exc:  # noqa: BLE001 (whatever Matplotlib raised goes to the summary)
        notes.append(f"plot {path.name} not drawn: {type(exc).__name__}: {exc}")


def write_final_state(scene: dict, out: Path, system, q, lam: float, formats=None) -> list[str]:
    """The final state in the scene's output formats (``state.<format>``)."""
    files = []
    for fmt in formats if formats is not None else scene["output"]["formats"]:
        path = out / f"state.{fmt}"
        if fmt == "compas":
            from ..io.compas_graph import write_compas_graph

            path = write_compas_graph(out / "state.compas.json", system, q, lam)
        elif fmt == "xdmf":
            write_series(path, system, [(lam, q, lam)], time_name="load factor")
            files.append(path.with_suffix(".h5").name)
        elif fmt == "3dm":
            from ..io.rhino import critical_modes, structure_3dm

            traced = scene["analysis"]["type"] == "continuation"
            structure_3dm(path, system, q, lam, critical_modes(out) if traced else ())
        else:
            write_state(path, system, q, lam)
        files.append(path.name)
    return files


def build_scene_model(scene: dict, progress: Progress):
    model = scenes.build_model(scene)
    if model.imperfection:
        progress("imperfection: " + ", ".join(f"{k} {v}" for k, v in model.imperfection.items()))
    return model
