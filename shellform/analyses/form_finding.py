"""Find a form, export it, then check whether it snaps.

:func:`run_mra_case` form-finds one MRA case (:func:`shellform.mra.solve_mra_case`)
and writes its meshes and summary. :func:`run_form_finding` runs an MRA
form-finding scene through it: the relaxation state is checkpointed every
few seconds (``relaxation_checkpoint.npz``, written atomically) so that
``--resume`` restarts from the last saved state, and the found form is
exported for design: the inverted shell as a quad surface mesh
(``inverted_shell.vtu``) and, when asked, a Rhino file (``form.3dm``) with the
hanging net, the inverted net, the shell surface and the grid lines as
polylines (the centrelines of the laths or rods that build it).

:func:`run_form_and_buckle` goes on: the hanging net, mirrored (Hooke), is
built as a gridshell of discrete elastic rods: every grid line becomes one
continuous rod through the shared grid nodes, pinned at the suspension points
with the twist of the edges there held. The rods are either straight when
unstressed (``rest_shape = "straight"``, an elastic gridshell bent into the
found form from straight laths, as the Mannheim Multihalle was; the prestress
of bending is relaxed first) or stress-free in the found shape (``"found"``).
Joints couple positions only, as in the gridshell paper, so rods can roll
about their axes; naturally curved rods of circular section do so under load.
Its self-weight (the load the form was found for) is then scaled by a load
factor and the equilibrium path is traced by arc-length continuation up to the
first limit or bifurcation point: the load factor there is the shell's
buckling safety against its own design load.
"""

from __future__ import annotations

import hashlib
import json
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from ..errors import MechanismError, ModelError, SceneError
from ..errors import CheckpointMismatch
from ..io.checkpoint import load_checkpoint, save_checkpoint
from ..io.net_meshes import write_net_meshes
from ..io.summary import write_json

ROD_DEFAULTS = {"E": 210.0e9, "radius": 0.02, "density": 0.0}
RELAXATION_CHECKPOINT = "relaxation_checkpoint.npz"
Progress = Callable[[str], None]


def grid_lines(grid) -> list[np.ndarray]:
    """Node chains of every grid line of a structured quad grid (both families)."""
    if not grid.structured:
        raise SceneError("geometry", "rods along grid lines need a structured grid (rectangle, ellipse, disk, "
                         "bspline, or a four-sided planform meshed as quads); this net is unstructured")
    index = grid.index()
    lines = []
    for family in (index, index.T):
        for row in family:
            chain = row[row >= 0]
            if len(chain) >= 3:
                lines.append(chain)
    return lines


NET_PARTS = ("geometry", "supports", "ropes", "masses", "loads")


def _fingerprint(params: dict) -> str:
    """What a saved state depends on: a hash of each part of the net (JSON text)."""
    net = {k: params[k] for k in NET_PARTS + ("cables",) if k in params}
    # the strain limit only decides which ropes a report names
    net["ropes"] = {k: v for k, v in net["ropes"].items() if k != "strain_limit"}
    return json.dumps({k: hashlib.sha256(json.dumps(v, sort_keys=True, default=str).encode()).hexdigest()[:16]
                       for k, v in net.items()}, sort_keys=True)


class NetCheckpointMismatch(SceneError, CheckpointMismatch):
    """A relaxation checkpoint of another net (a scene error and a refused checkpoint)."""


class RelaxationCheckpoint:
    """Saves the state of a relaxation at most every ``interval`` seconds (a progress callback).

    Parameters
    ----------
    path : path-like
        The ``.npz`` file (written atomically).
    interval : float
        Seconds of wall time between saves (0: at every progress call).
    fingerprint : str
        Identifies the net; :meth:`load` refuses a file of another net.
    """

    def __init__(self, path, interval: float, fingerprint: str):
        self.path = Path(path)
        self.interval = float(interval)
        self.fingerprint = fingerprint
        self.last = -np.inf
        self.saves = 0

    def save(self, q, v, iteration: int, scheme: str, converged: bool = False) -> None:
        save_checkpoint(self.path, q=q, v=v, iteration=iteration, scheme=scheme, converged=converged,
                        fingerprint=self.fingerprint)
        self.last = time.perf_counter()
        self.saves += 1

    def __call__(self, info) -> None:
        if info.q is not None and time.perf_counter() - self.last >= self.interval:
            self.save(info.q, info.v, info.iteration, info.scheme)

    def load(self) -> dict | None:
        """The saved state, or None when there is none."""
        data = load_checkpoint(self.path)
        if data is None:
            return None
        saved = str(data["fingerprint"])
        if saved != self.fingerprint:
            try:
                saved_parts = json.loads(saved)
            except ValueError:  # the single hash of an older checkpoint
                saved_parts = {}
            now = json.loads(self.fingerprint)
            changed = [k for k in now if saved_parts.get(k) != now[k]] if saved_parts else list(NET_PARTS)
            raise NetCheckpointMismatch(
                "--resume", f"{self.path} holds the state of a different net ({', '.join(changed)} "
                f"{'differ' if len(changed) > 1 or changed[0].endswith('s') else 'differs'}); delete it or run "
                "without --resume")
        return data


def _resume_state(checkpoint: RelaxationCheckpoint, params: dict, resume: bool, say: Progress):
    if not resume:
        return None, None
    data = checkpoint.load()
    if data is None:
        say(f"no relaxation checkpoint in {checkpoint.path.parent}: starting from the start shape")
        return None, None
    scheme = params["solver"]["scheme"]
    same = str(data["scheme"]) == scheme and scheme != "implicit"
    say(f"resuming the relaxation from {checkpoint.path.name} (iteration {int(data['iteration'])} of the "
        f"{data['scheme']} scheme)")
    # an explicit run continues on its trajectory; the implicit scheme starts from rest
    return data["q"], data["v"] if same else None


# -- the files of a found form -----------------------------------------------------------------


def run_mra_case(params: dict, out_dir, progress: Progress | None = None, *, export=None,
                 summary_file: str | None = "summary.json", **solve) -> dict:
    """Form-find one case and write its results.

    Parameters
    ----------
    params, progress
        See :func:`shellform.mra.solve_mra_case`.
    out_dir : path-like
        Directory for ``hanging.vtu``, ``inverted.vtu`` and ``summary.json``.
    export : callable, optional
        ``export(result, inverted, out_dir) -> list of file names``: further
        files written after the meshes (``inverted`` is None when the
        inversion failed).
    summary_file : str or None
        Name of the summary written to ``out_dir``; None: none (a caller that
        runs more stages writes one summary of them all).
    **solve
        Passed to :func:`shellform.mra.solve_mra_case` (``q0``, ``v0``,
        ``callback``, ``grid``).

    Returns
    -------
    dict
        The case's summary, with the ``files`` written and the ``wall_time_s`` of it all.
    """
    from ..mra.case import solve_mra_case

    t0 = time.perf_counter()
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    case = solve_mra_case(params, progress, **solve)
    files = []
    if case.meshes:
        files += write_net_meshes(out, case.result, case.inverted)
        if case.length_control is not None:
            files += write_net_meshes(out, case.length_control.result, case.length_control_inverted,
                                      tag="_length_control")
    if export is not None:
        files += export(case.result, case.inverted, out)
    summary = case.summary
    summary["files"] = files + ["summary.json"]
    summary["wall_time_s"] = time.perf_counter() - t0
    if summary_file is not None:
        write_json(out / summary_file, summary)
    return summary


# -- exports of a found form ------------------------------------------------------------------


def export_form(scene: dict, res, inv, out: Path) -> list[str]:
    """The inverted shell as a quad surface (VTU) and the form as Rhino geometry (when asked)."""
    from ..io.shell import write_surface

    files = []
    net = res.net
    if inv is None:
        return files
    support = np.zeros(net.structure.n_nodes)
    support[net.supports] = 1.0
    height = inv.positions[:, 2] - inv.plane_z
    faces = net.grid.faces
    if scene["output"]["meshes"] and faces:
        write_surface(out / "inverted_shell.vtu", inv.positions, list(faces.values()),
                      {"support": support, "height": height})
        files.append("inverted_shell.vtu")
    if "3dm" in scene["output"]["formats"]:
        from ..io.rhino import write_3dm
        from ..mra.lengths import tolerance_classes

        x = inv.positions
        classes = tolerance_classes(res.length, scene["analysis"]["lengths"]["tolerance"])
        write_3dm(out / "form.3dm",
                  lines={"hanging net": (res.positions, net.rope_edges), "inverted net": (x, net.rope_edges)},
                  polylines={"centrelines": [x[c] for c in grid_lines(net.grid)] if net.grid.structured else []},
                  meshes={"inverted shell": (x, np.concatenate([f[:, [0, 1, 2, 2]] if f.shape[1] == 3 else f
                                                                for f in faces.values()]))} if faces else {},
                  line_text={"hanging net": {"axial_force [N]": res.tension, "slack [-]": res.slack,
                                             "length [m]": res.length, "length_class [-]": classes},
                             "inverted net": {"axial_force [N]": inv.force, "length [m]": res.length,
                                              "length_class [-]": classes}})
        files.append("form.3dm")
    return files


def _find_form(scene: dict, out: Path, progress: Progress, resume: bool, keep: dict | None = None) -> dict:
    """Run the form finding with checkpoints and exports; ``keep`` receives the result objects."""
    from ..geometry.meshnet import mesh_net
    from ..scene import mra_params

    params = mra_params(scene)
    grid = None
    if scene["source"] == "file":
        m = scene["mesh"]
        try:
            grid = mesh_net(m.points, m.cells, m.point_sets)
        except ModelError as exc:
            raise SceneError("geometry.file", str(exc)) from None
    checkpoint = RelaxationCheckpoint(out / RELAXATION_CHECKPOINT,
                                      scene["analysis"]["relaxation"]["checkpoint_interval"], _fingerprint(params))
    q0, v0 = _resume_state(checkpoint, params, resume, progress)

    def export(res, inv, out_dir):
        r = res.relaxation
        checkpoint.save(r.q, r.v, r.iterations, r.scheme, converged=bool(res.converged))
        if keep is not None:
            keep.update(result=res, inverted=inv)
        return export_form(scene, res, inv, Path(out_dir)) + [RELAXATION_CHECKPOINT]

    try:
        # the caller writes summary.json, with the stages of the whole run
        summary = run_mra_case(params, out, progress, q0=q0, v0=v0, callback=checkpoint, export=export,
                               summary_file=None, grid=grid)
    except ModelError as exc:
        # the net could not be built or held: name the part of the scene that describes it
        text = str(exc)
        where = "supports" if isinstance(exc, MechanismError) or any(
            w in text for w in ("support", "grid position", "frame")) else "geometry"
        raise SceneError(where, text) from None
    summary["checkpoints_written"] = checkpoint.saves
    return summary


def run_form_finding(scene: dict, out_dir, progress: Progress | None = None, resume: bool = False) -> dict:
    """Form-find a validated planform scene and write its results (see the module docstring)."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    summary = _find_form(scene, out, progress or (lambda msg: None), resume)
    summary.setdefault("analysis", "mra")
    return summary
