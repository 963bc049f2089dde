"""Find a form, export it, then check whether it snaps.

:func:`run_form_finding` runs an MRA form-finding scene through
:func:`shellform.mra.run_mra_case`: the relaxation state is checkpointed every
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

from .errors import MechanismError, ModelError, SceneError
from .io.checkpoint import CheckpointMismatch, load_checkpoint, save_checkpoint
from .io.summary import RunRecord
from .model import Structure

#: rod section of the gridshell built on a found form when [rods] leaves it open
ROD_DEFAULTS = {"E": 210.0e9, "radius": 0.02, "density": 0.0}
RELAXATION_CHECKPOINT = "relaxation_checkpoint.npz"

Progress = Callable[[str], None]


def grid_lines(grid) -> list[np.ndarray]:
    """Node chains of every grid line of a structured quad grid (both families)."""
    index = grid.index()
    lines = []
    for family in (index, index.T):
        for row in family:
            chain = row[row >= 0]
            if len(chain) >= 3:
                lines.append(chain)
    return lines


def dome_rods(result, section: dict, plane_z: float | None = None):
    """The inverted hanging net as a rod gridshell, loaded by its own form-finding weight.

    Returns
    -------
    structure : Structure
    network : RodNetwork
    """
    from .mra.inversion import MIRROR
    from .rods.network import RodNetwork

    net = result.net
    x = result.positions
    plane = float(x[net.supports, 2].max()) if plane_z is None else plane_z
    xi = x * MIRROR
    xi[:, 2] += 2.0 * plane
    s = Structure(xi)
    s.add_point_mass(np.arange(len(xi)), net.structure.nodal_mass())
    g = net.structure.gravity if net.structure.gravity is not None else np.array([0.0, 0.0, -9.81])
    s.set_gravity(g)  # the shell carries the weight the net hung under, downward
    network = RodNetwork(s)
    for k, chain in enumerate(grid_lines(net.grid)):
        network.add_rod(chain, name=f"rod{k}", **section)
    s.fix(net.supports)
    # hold the twist of every edge that touches a suspension point: a pinned
    # rod end with free twist could spin about its own axis
    support = np.zeros(s.n_nodes, dtype=bool)
    support[net.supports] = True
    for rod in network.rods:
        touches = support[rod.nodes[:-1]] | support[rod.nodes[1:]]
        s.fix_dofs(rod.twist_dofs[touches])
    return s, network


# -- checkpoints of the relaxation ------------------------------------------------------------


#: the parts of a form-finding scene a relaxation state depends on (not the solver
#: settings: a resumed run may change the scheme or the tolerance and still finds the same rest)
NET_PARTS = ("geometry", "supports", "ropes", "masses", "loads")


def _fingerprint(params: dict) -> str:
    """What a saved state depends on: a hash of each part of the net (JSON text)."""
    net = {k: params[k] for k in NET_PARTS}
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


# -- exports of a found form ------------------------------------------------------------------


def export_form(scene: dict, res, inv, out: Path) -> list[str]:
    """The inverted shell as a quad surface (VTU) and the form as Rhino geometry (when asked)."""
    from .io.shell import write_surface

    files = []
    net = res.net
    if inv is None:
        return files
    support = np.zeros(net.structure.n_nodes)
    support[net.supports] = 1.0
    height = inv.positions[:, 2] - inv.plane_z
    if scene["output"]["meshes"]:
        write_surface(out / "inverted_shell.vtu", inv.positions, net.grid.quads,
                      {"support": support, "height": height})
        files.append("inverted_shell.vtu")
    if "3dm" in scene["output"]["formats"]:
        from .io.rhino import write_3dm

        x = inv.positions
        write_3dm(out / "form.3dm",
                  lines={"hanging net": (res.positions, net.rope_edges), "inverted net": (x, net.rope_edges)},
                  polylines={"centrelines": [x[c] for c in grid_lines(net.grid)]},
                  meshes={"inverted shell": (x, net.grid.quads)})
        files.append("form.3dm")
    return files


def _find_form(scene: dict, out: Path, progress: Progress, resume: bool, keep: dict | None = None) -> dict:
    """Run the form finding with checkpoints and exports; ``keep`` receives the result objects."""
    from .mra.case import run_mra_case
    from .scene import mra_params

    params = mra_params(scene)
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
                               summary_file=None)
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


def _section(scene: dict) -> dict:
    from .rods.network import circular_section

    rods = scene["rods"] or {}
    value = {k: (rods.get(k) if rods.get(k) is not None else d) for k, d in ROD_DEFAULTS.items()}
    E = value["E"]
    G = rods.get("G") or E / 2.6
    section = circular_section(E=E, G=G, radius=value["radius"], density=value["density"])
    section["natural_curvature"] = "straight" if rods.get("rest_shape", "straight") == "straight" else "rest"
    return {"section": section, "E": E, "G": G, "radius": value["radius"],
            "rest_shape": rods.get("rest_shape", "straight")}


def run_form_and_buckle(scene: dict, out_dir, progress: Progress | None = None, resume: bool = False,
                        record: RunRecord | None = None) -> dict:
    """Form-find a validated planform scene, then trace the buckling of its rod gridshell.

    The rod section is ``[rods]`` (``E``, ``G``, ``radius``, ``density``,
    ``rest_shape``), the continuation bounds ``[analysis.buckling]``. Writes
    the form-finding files and ``buckling_path.csv``, ``buckling_path.xdmf``,
    ``buckling_curve.png``, ``buckling_path_events.json`` and the path's
    checkpoint. ``record`` (the run's summary) is told when each of the two
    stages, ``form_finding`` and ``buckling``, starts and ends, so that a
    run killed while buckling leaves a summary that says so.
    """
    from .io import write_series
    from .pipeline import run_continuation_case
    from .rods.network import build_rod_system
    from .solvers import solve_static

    say = progress or (lambda msg: None)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    b = scene["analysis"]["buckling"]

    def stage(method, *args, **kwargs):
        if record is not None:
            getattr(record, method)(*args, **kwargs)

    found: dict = {}
    stage("start", "form_finding")
    summary = _find_form(scene, out, say, resume, keep=found)
    summary["analysis"] = "form_and_buckle"
    summary["form_finding_wall_time_s"] = summary.pop("wall_time_s")
    form = found["result"]
    stage("finish", "form_finding", bool(form.converged), summary.get("message"), body=summary)
    if not form.converged:
        # buckling of a form that was not found would answer another question: not run
        return summary
    stage("start", "buckling", body=summary)
    sec = _section(scene)
    structure, network = dome_rods(form, sec["section"])
    system = build_rod_system(network, gravity_scaled=True)
    q_start = None
    if sec["rest_shape"] == "straight":
        # laths bent into the found shape: let the bending prestress settle, unloaded
        erected = solve_static(system, lam=0.0)
        say(f"erection (prestress relaxed, no load): {erected.message}")
        if not erected.success:
            summary = {**summary, "converged": False, "message": f"erection failed: {erected.message}"}
            stage("finish", "buckling", False, summary["message"], body=summary)
            return summary
        q_start = erected.q
        system.accept(q_start)
    apex = int(np.argmax(structure.nodes[:, 2]))
    say(f"buckling of the inverted shell: {len(network.rods)} rods, {system.n_free} free DOFs; "
        f"self-weight scaled by the load factor up to {b['load_factor_max']}")
    options = dict(parameter_bounds=(0.0, b["load_factor_max"]), max_steps=b["max_steps"], stop_after_events=1,
                   monitors={"apex_w": 3 * apex + 2}, q0=q_start)
    if b["initial_increment"] is not None:
        options["initial_increment"] = b["initial_increment"]
    path, path_summary = run_continuation_case(
        system, out, "load", name="buckling_path", progress=say, resume=resume,
        checkpoint_every=b["checkpoint_every"], plot_file="buckling_curve.png", x="apex_w",
        xlabel="apex z-displacement [m]", ylabel="load factor on self-weight",
        title="inverted shell under its own weight", event_x=lambda e: e.q[3 * apex + 2] - structure.nodes[apex, 2],
        **options)
    write_series(out / "buckling_path.xdmf", system,
                 [(step, q, path.table["lam"][step]) for step, q in zip(path.state_steps, path.states)])
    first = path.events[0] if path.events else None
    summary["buckling"] = {
        "converged": bool(path.success),
        "message": path.message,
        "steps": int(path.steps),
        "critical_load_factor": float(first.lam) if first else None,
        "critical_kind": first.kind if first else None,
        "max_load_factor_traced": float(np.max(path["lam"])),
        "n_rods": len(network.rods),
        "n_free_dof": int(system.n_free),
        "section": {"E": sec["E"], "G": sec["G"], "radius": sec["radius"]},
        "rest_shape": sec["rest_shape"],
    }
    summary["converged"] = bool(summary["converged"] and path.success)
    summary["files"] = summary.get("files", []) + path_summary["files"] + ["buckling_path.xdmf"]
    if "warnings" in path_summary:
        summary["warnings"] = summary.get("warnings", []) + path_summary["warnings"]
    summary["wall_time_s"] = time.perf_counter() - t0
    stage("finish", "buckling", bool(path.success), path.message, body=summary)
    return summary
