"""Running scenes from Python.

:func:`run` runs a scene exactly as ``shellform run`` does and returns a
:class:`Result`: the summary, and the tables, states, buckling modes and
member fields of the files written, as NumPy arrays. The files are the one
record of a run, so what Python reads is what ParaView and Rhino show. Without
an output folder the run writes into a temporary folder that lives as long as
the result.
"""

from __future__ import annotations

import json
import tempfile
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

import numpy as np

from .errors import SceneError
from .progress import Progress

#: the main table of each analysis type
_TABLES = {"continuation": "path.csv", "form_and_buckle": "buckling_path.csv", "dynamics": "dynamics.csv",
           "indentation": "indentation.csv"}
#: the time series of each analysis type
_SERIES = {"continuation": "path.xdmf", "form_and_buckle": "buckling_path.xdmf", "dynamics": "dynamics.xdmf",
           "indentation": "indentation.xdmf"}


def builtin_scenes() -> list[str]:
    """Names of the scenes shipped with shellform (``default``, ``von_mises``, ...)."""
    folder = resources.files("shellform") / "scenes"
    return sorted(p.name[:-5] for p in folder.iterdir() if p.name.endswith(".toml"))


def builtin_scene_path(name: str) -> Path:
    """The file of a built-in scene."""
    path = resources.files("shellform") / "scenes" / f"{name}.toml"
    if not path.is_file():
        raise SceneError(name, f"no built-in scene of that name; built-in: {', '.join(builtin_scenes())}")
    return Path(str(path))


def scene_from_toml(text: str, base_dir=None) -> dict:
    """A checked scene from TOML text (relative file names are relative to ``base_dir``)."""
    from .scene import parse_scene
    from .scene.files import parse_toml

    return parse_scene(parse_toml(text), base_dir=base_dir)


def _scene(scene) -> dict:
    from .scene import load_scene

    if isinstance(scene, dict):
        return scene
    path = Path(scene)
    if path.suffix == ".toml" or path.exists():
        return load_scene(path)
    return load_scene(builtin_scene_path(str(scene)))


@dataclass
class States:
    """The states of a time series (``*.xdmf`` with its ``*.h5``).

    Attributes
    ----------
    time_name : str
        What ``times`` are (``"path parameter"``, ``"arc length"``, ``"time [s]"``, ...).
    times, load_factors : ndarray (k,)
    positions : list of ndarray (n, 3)
        The nodes of every state.
    points, cells : dict of name -> list of ndarray
        Point and cell fields of every state.
    cells_nodes : ndarray (m, 2)
        The line cells (members, then joints).
    """

    time_name: str
    times: np.ndarray
    load_factors: np.ndarray
    positions: list
    points: dict
    cells: dict
    cells_nodes: np.ndarray
    units: dict = field(default_factory=dict)

    @classmethod
    def read(cls, h5_path) -> States:
        import h5py

        with h5py.File(h5_path, "r") as h5:
            keys = sorted(h5["states"], key=int) if "states" in h5 else []
            states = [h5[f"states/{k}"] for k in keys]
            point_names = list(states[0]["point"]) if states else []
            cell_names = list(states[0]["cell"]) if states else []
            return cls(
                time_name=str(h5.attrs["time_name"]),
                times=np.array([g.attrs["time"] for g in states]),
                load_factors=np.array([g.attrs["load_factor"] for g in states]),
                positions=[g["points"][()] for g in states],
                points={n: [g[f"point/{n}"][()] for g in states] for n in point_names},
                cells={n: [g[f"cell/{n}"][()] for g in states] for n in cell_names},
                cells_nodes=h5["cells"][()] if "cells" in h5 else np.zeros((0, 2), dtype=np.int64),
                units=json.loads(h5.attrs["units"]) if "units" in h5.attrs else {},
            )


class Result:
    """The outcome of :func:`run`: the summary and the arrays of the files written.

    Attributes
    ----------
    scene : dict
        The checked scene that ran.
    folder : Path
        The output folder.
    summary : dict
        What ``summary.json`` holds.
    """

    def __init__(self, scene: dict, folder: Path, summary: dict, keep=None):
        self.scene = scene
        self.folder = Path(folder)
        self.summary = summary
        self._keep = keep  # a temporary folder: deleted with the result

    @property
    def converged(self) -> bool:
        return bool(self.summary.get("converged", False))

    @property
    def message(self) -> str:
        return str(self.summary.get("message", ""))

    @property
    def analysis(self) -> str:
        return self.scene["analysis"]["type"]

    @property
    def files(self) -> list[str]:
        return list(self.summary.get("files", []))

    @property
    def warnings(self) -> list[str]:
        return list(self.summary.get("warnings", []))

    def table(self, name: str | None = None) -> dict[str, np.ndarray]:
        """A CSV table of the run by column name (default: the analysis's main table)."""
        from .io.table import read_csv

        name = name or _TABLES.get(self.analysis)
        if name is None or not (self.folder / name).is_file():
            raise FileNotFoundError(f"{self.analysis} run: no table {name!r} in {self.folder}")
        return read_csv(self.folder / name)

    @property
    def events(self) -> list[dict]:
        """The critical points located along the path, in order (``number``, ``kind``, ``lam``, ``file``, ...)."""
        stem = Path(_SERIES.get(self.analysis, "path.xdmf")).stem
        events = self.folder / f"{stem}_events.json"
        return json.loads(events.read_text())["events"] if events.is_file() else []

    def mode(self, number: int = 1) -> np.ndarray:
        """The buckling mode of critical point ``number`` (1-based), shape (n_nodes, 3), largest nodal value 1."""
        import meshio

        match = [e for e in self.events if e.get("number") == number]
        if not match:
            raise KeyError(f"no critical point {number}; the run located {len(self.events)}")
        return meshio.read(self.folder / match[0]["file"]).point_data["mode"]

    def states(self, name: str | None = None) -> States:
        """The time series of the run (default: the analysis's own)."""
        name = name or _SERIES.get(self.analysis)
        if name is None or not (self.folder / name).is_file():
            raise FileNotFoundError(f"{self.analysis} run: no time series {name!r} in {self.folder}")
        return States.read((self.folder / name).with_suffix(".h5"))

    def mesh(self, name: str = "state.vtu"):
        """A mesh the run wrote, as a ``meshio.Mesh`` (points, cells, point and cell data)."""
        import meshio

        return meshio.read(self.folder / name)


def run(scene, out=None, progress: Progress | None = None, resume: bool = False) -> Result:
    """Run a scene; return its :class:`Result`.

    Parameters
    ----------
    scene : dict, path or str
        A checked scene (:func:`~shellform.scene.load_scene`,
        :func:`scene_from_toml`), a scene file, or the name of a built-in scene.
    out : path-like, optional
        Output folder; default a temporary folder deleted with the result.
    progress : callable, optional
        Receives the progress messages (:mod:`shellform.progress`).
    resume : bool
        Continue an interrupted run from its checkpoint in ``out``.
    """
    from .analyses import run_scene

    scene = _scene(scene)
    keep = None
    if out is None:
        keep = tempfile.TemporaryDirectory(prefix="shellform-")
        out = keep.name
    summary = run_scene(scene, out, progress, resume=resume)
    return Result(scene, Path(out), summary, keep)
