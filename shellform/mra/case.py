"""One MRA form-finding case from a parameter dictionary, start to finish.

:func:`solve_mra_case` builds the grid, the hanging net and its start state,
form-finds, inverts, computes the length statistics (and optionally runs the
length control and the flat-versus-surface start comparison), and returns the
summary with the results; it writes no files
(:func:`shellform.analyses.form_finding.run_mra_case` writes the meshes and
``summary.json``). The parameter layout (the ``[mra]`` scene tables) is documented in
``validation/mra/README.md``; every key has a default except the geometry
and the supports.
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass, fields

import numpy as np

from ..errors import ModelError, SceneError
from ..geometry.bspline import BSplineSurface, dish, height_field
from ..geometry.grids import QuadGrid, bspline_surface_grid, ellipse_grid, rectangle_grid
from ..geometry.meshnet import MeshNet
from ..geometry.planforms import BoundaryCurve, curve_planform, polygon_planform, surface_planform
from ..solvers.relaxation import START_STATES, Refinements, RelaxationOptions
from .formfind import (STRAIN_LIMIT, FormFindingResult, HypostaticWarning, OverstretchWarning, coarse_net_outcome,
                       coarse_net_progress, form_find)
from .inversion import InvertedShell, invert
from .lengths import LengthControlResult, control_lengths, length_statistics
from .net import HangingNet, hanging_net
from .start import coarse_force_density_start, fit_height_field, surface_start

#: the relaxation options a case's ``solver`` table sets (their defaults are those of RelaxationOptions)
_OPTION_KEYS = ("scheme", "rtol", "velocity_tol", "acceleration_tol", "max_iterations", "max_wall_time", "damping",
                "linear_solver", "dt")
#: the refinements a ``solver`` table may switch (to measure their gain; all on by default)
_REFINEMENT_KEYS = tuple(f.name for f in fields(Refinements))


def _solver_defaults() -> dict:
    """The ``solver`` table's defaults, from :class:`RelaxationOptions` and :class:`Refinements`."""
    options, refinements = RelaxationOptions(), Refinements()
    return {**{k: getattr(options, k) for k in _OPTION_KEYS}, "start": START_STATES[0],
            **{k: getattr(refinements, k) for k in _REFINEMENT_KEYS}}


DEFAULTS = {
    "name": "mra",
    "geometry": {},
    "supports": {},
    "ropes": {"slack": 0.0, "EA": None, "stiffness_ratio": 1.0e4, "mass_per_length": 1.0, "strain_limit": STRAIN_LIMIT},
    "cables": [],
    "masses": {"node_mass": 0.0},
    "loads": {"gravity": [0.0, 0.0, -9.81]},
    "solver": _solver_defaults(),
    "start": {"type": "flat", "depth": None, "control_heights": None, "coarsening": 4, "n_ctrl": 6,
              "compare_flat": False},
    "lengths": {"tolerance": 0.01, "target": None, "control": False, "n_classes": 3, "rounds": 4},
    "output": {"meshes": True},
}


def _merge(params: dict) -> dict:
    """Parameters over the defaults, refusing unknown keys."""
    unknown = set(params) - set(DEFAULTS) - {"description", "title", "analysis", "reference"}
    if unknown:
        raise SceneError(", ".join(sorted(unknown)), f"unknown MRA case key(s); expected {sorted(DEFAULTS)}")
    out = {}
    for key, default in DEFAULTS.items():
        given = params.get(key, {} if isinstance(default, dict) else default)
        if key == "supports" and isinstance(given, list):
            out[key] = given  # several entries, each with its own dofs
        elif isinstance(default, dict):
            if not isinstance(given, dict):
                raise SceneError(key, f"expected a table, got {type(given).__name__}")
            if key not in ("geometry", "supports"):
                bad = set(given) - set(default)
                if bad:
                    raise SceneError(f"{key}.{sorted(bad)[0]}", f"unknown key; expected one of {sorted(default)}")
            out[key] = {**default, **given}
        else:
            out[key] = given
    for key in ("description", "title", "reference"):
        if key in params:
            out[key] = params[key]
    return out


def build_grid(geometry: dict) -> QuadGrid | MeshNet:
    """The planform grid of a case (see the README for the keys of each type).

    A mesh file (``type = "file"``) is read by the caller and passed to
    :func:`build_net` as its grid (reading files belongs to ``shellform.io``).
    """
    kind = geometry.get("type")
    try:
        if kind in ("polygon", "curves", "surface"):
            return _meshed_planform(geometry)
        if kind == "rectangle":
            return rectangle_grid(float(geometry["length_x"]), float(geometry["length_y"]),
                                  int(geometry["n_i"]), int(geometry["n_j"]), geometry.get("origin", (0, 0, 0)))
        if kind == "ellipse":
            return ellipse_grid(float(geometry["a"]), float(geometry["b"]), int(geometry["n"]),
                                geometry.get("center", (0, 0, 0)))
        if kind == "disk":
            r = float(geometry["radius"])
            return ellipse_grid(r, r, int(geometry["n"]), geometry.get("center", (0, 0, 0)))
        if kind == "bspline":
            srf = BSplineSurface(np.asarray(geometry["control_points"], dtype=float),
                                 int(geometry.get("degree_u", 3)), int(geometry.get("degree_v", 3)),
                                 weights=geometry.get("weights"))
            return bspline_surface_grid(srf, int(geometry["n_i"]), int(geometry["n_j"]))
    except KeyError as exc:
        raise SceneError(f"geometry.{exc.args[0]}", f"required for geometry type {kind!r}") from None
    raise SceneError("geometry.type", f"expected 'rectangle', 'ellipse', 'disk', 'bspline', 'polygon', 'curves' or "
                     f"'surface', got {kind!r}")


def _meshed_planform(geometry: dict) -> QuadGrid | MeshNet:
    """A gmsh planform of any shape: a polygon with holes, B-spline boundary curves, or a surface file."""
    kind = geometry["type"]
    mesh = {"edge_length": float(geometry["edge_length"]), "elements": geometry.get("elements", "quads")}
    try:
        if kind == "polygon":
            return polygon_planform(geometry["boundary"], geometry.get("holes", ()), **mesh)
        if kind == "curves":
            curves = geometry["curves"]
            n_loops = max(int(c.get("loop", 0)) for c in curves) + 1
            loops = [[BoundaryCurve(np.asarray(c["control_points"], dtype=float), int(c.get("degree", 3)),
                                    None if c.get("weights") is None else np.asarray(c["weights"], dtype=float))
                      for c in curves if int(c.get("loop", 0)) == k] for k in range(n_loops)]
            return curve_planform(loops, **mesh)
        return surface_planform(geometry["file"], **mesh)
    except ModelError as exc:
        raise SceneError("geometry", str(exc)) from None


def build_net(p: dict, grid: QuadGrid | MeshNet | None = None) -> HangingNet:
    """The hanging net of merged case parameters (on ``grid`` when given)."""
    grid = build_grid(p["geometry"]) if grid is None else grid
    r = p["ropes"]
    return hanging_net(grid, p["supports"], slack=r["slack"], EA=r["EA"], stiffness_ratio=r["stiffness_ratio"],
                       mass_per_length=r["mass_per_length"], node_mass=p["masses"]["node_mass"],
                       gravity=p["loads"]["gravity"], cables=tuple(p["cables"]))


def _solver_options(p: dict, progress: Callable[[str], None] | None) -> dict:
    """The keywords of :func:`~shellform.mra.formfind.form_find` for the case's ``solver`` table."""
    s = p["solver"]
    opts = {k: s[k] for k in _OPTION_KEYS}
    if opts["max_iterations"] is not None:
        opts["max_iterations"] = int(opts["max_iterations"])
    refinements = Refinements(**{k: bool(s[k]) for k in _REFINEMENT_KEYS})
    opts = {"options": RelaxationOptions(**opts, refinements=refinements), "start": s["start"],
            "strain_limit": float(p["ropes"]["strain_limit"])}
    if progress is not None:
        def cb(info):
            progress(f"  {info.scheme} iteration {info.iteration}: max velocity {info.max_velocity:.3e} m/s, "
                     f"max acceleration {info.max_acceleration:.3e} m/s^2")
        opts["callback"] = cb
    return opts


def planform_box(net: HangingNet):
    x = net.grid.nodes
    return (float(x[:, 0].min()), float(x[:, 0].max())), (float(x[:, 1].min()), float(x[:, 1].max()))


def start_state(p: dict, net: HangingNet, options: dict,
                progress: Callable[[str], None] | None = None) -> tuple[np.ndarray | None, dict]:
    """The start state of a case and a note on how it was made (with its cost).

    ``progress`` receives the steps of the coarse net a ``coarse_*`` start hangs first.
    """
    st = p["start"]
    kind = st["type"]
    if kind == "flat":
        return None, {"type": "flat"}
    t0 = time.perf_counter()
    xr, yr = planform_box(net)
    if kind == "nurbs":
        if st["control_heights"] is not None:
            hf = height_field(np.asarray(st["control_heights"], dtype=float), xr, yr)
        else:
            depth = st["depth"]
            if depth is None:
                raise SceneError("start.depth", "a 'nurbs' start needs control_heights or a depth")
            hf = dish(xr, yr, float(depth))
        q0 = surface_start(net, hf)
        return q0, {"type": "nurbs", "preparation_s": time.perf_counter() - t0}
    if kind in ("coarse_nurbs", "coarse_force_density"):
        # the preliminary phase: hang a coarser version of the same net
        coarse_net = build_net(_coarsened(p, int(st["coarsening"])))
        with warnings.catch_warnings():
            # a coarse net often has too few free nodes for Eqs. (11)-(12); it only shapes the
            # start, and the full net reports its own stretched ropes
            warnings.simplefilter("ignore", HypostaticWarning)
            warnings.simplefilter("ignore", OverstretchWarning)
            shown = {"progress": progress, "callback": coarse_net_progress(progress)} if progress else {"callback": None}
            coarse = form_find(coarse_net, **{**options, **shown})
        if progress:
            progress(coarse_net_outcome(coarse, time.perf_counter() - t0))
        if kind == "coarse_nurbs":
            # a B-spline height field fitted to the coarse net carries the full net's nodes
            pts = coarse.positions.copy()
            pts[:, 2] -= coarse_net.structure.nodes[:, 2]
            q0 = surface_start(net, fit_height_field(pts, xr, yr, n_ctrl=int(st["n_ctrl"])))
        else:
            # the coarse ropes' force densities, carried over to the full net's ropes: its shape in
            # balance with them has ropes close to their rest lengths
            q0 = coarse_force_density_start(coarse, net)
            if q0 is None:
                raise SceneError("start.type", "the force densities of the coarse net do not hold every "
                                 "free node of the full net; use 'coarse_nurbs' or 'flat'")
        return q0, {"type": kind, "preparation_s": time.perf_counter() - t0,
                    "coarse_iterations": int(coarse.relaxation.iterations),
                    "coarse_converged": bool(coarse.converged), "coarse_nodes": int(coarse_net.structure.n_nodes)}
    raise SceneError("start.type",
                     f"expected 'flat', 'nurbs', 'coarse_nurbs' or 'coarse_force_density', got {kind!r}")


def _coarsened(p: dict, factor: int) -> dict:
    """The same case on a grid ``factor`` times coarser (structured positions scaled)."""
    g = dict(p["geometry"])
    if g["type"] not in ("rectangle", "ellipse", "disk", "bspline"):
        raise SceneError("start.type", f"a coarse start needs a grid of divisions (rectangle, ellipse, disk, bspline); "
                         f"geometry type {g['type']!r} has an edge length: use 'flat' or 'nurbs'")
    if not isinstance(p["supports"], dict) or p["cables"]:
        raise SceneError("start.type", "a coarse start needs one set of suspension points held alike and no edge "
                         "cables: use 'flat' or 'nurbs'")
    keys = [k for k in ("n_i", "n_j", "n") if k in g]
    old = {k: int(g[k]) for k in keys}
    for k in keys:
        if old[k] % factor:
            raise SceneError(f"geometry.{k}", f"{old[k]} divisions cannot be coarsened by {factor}")
        g[k] = old[k] // factor
    sup = dict(p["supports"])

    def scale(pos):
        return [[int(a) // factor if a >= 0 else -((-int(a) - 1) // factor) - 1 for a in ij] for ij in pos]

    if "positions" in sup:
        sup["positions"] = scale(sup["positions"])
    if "frames" in sup:
        sup["frames"] = [{**f, "from": scale([f["from"]])[0], "to": scale([f["to"]])[0]} for f in sup["frames"]]
    if "nodes" in sup:
        raise SceneError("supports.nodes", "a coarse start needs supports by groups, positions or frames")
    return {**p, "geometry": g, "supports": sup}


@dataclass
class MraCase:
    """A form-found case: its summary and the results its files are written from.

    Attributes
    ----------
    summary : dict
        JSON-ready: ``converged``, ``iterations``, ``max_velocity``,
        ``max_acceleration``, ``n_slack_ropes``, ``rise``, ``rope_lengths``
        (statistics) and more (hypostatic check, reactions, inversion, start
        comparison, length control); no files and no total wall time yet.
    result : FormFindingResult
    inverted : InvertedShell or None
        None when the inversion failed (``summary["inverted"]["error"]`` says why).
    meshes : bool
        Whether the case asks for its meshes (``output.meshes``).
    length_control : LengthControlResult, optional
        When the case asks for the length control.
    length_control_inverted : InvertedShell, optional
        Its inverted shell (only with ``meshes``; None when the inversion failed).
    """

    summary: dict
    result: FormFindingResult
    inverted: InvertedShell | None
    meshes: bool
    length_control: LengthControlResult | None = None
    length_control_inverted: InvertedShell | None = None


def _with_callback(options: dict, progress: Callable[[str], None] | None, callback) -> dict:
    """The form-finding keywords of the full net: the coarse nets' steps shown, ``callback`` called too."""
    main_options = dict(options)
    if progress is not None:
        main_options["progress"] = progress  # the coarse nets' steps, on large nets
    if callback is not None:
        shown = options.get("callback")
        main_options["callback"] = callback if shown is None else (lambda info: bool(shown(info)) | bool(callback(info)))
    return main_options


def _compare_flat(net: HangingNet, options: dict, res: FormFindingResult, start_note: dict, say) -> dict:
    """The same net from the flat planform: its cost and shape against the case's start."""
    # the planform itself, as in the paper (without q0 the implicit scheme would start
    # from the force-density shape)
    flat = form_find(net, None, **{**options, "start": "reference"})
    prep = start_note.get("preparation_s", 0.0)
    say(f"flat start: {flat.relaxation.iterations} iterations, {flat.relaxation.wall_time_s:.3g} s; "
        f"{start_note['type']} start: {res.relaxation.iterations} iterations, "
        f"{res.relaxation.wall_time_s + prep:.3g} s with its preparation")
    return {
        "flat": {"converged": bool(flat.converged), "iterations": int(flat.relaxation.iterations),
                 "wall_time_s": float(flat.relaxation.wall_time_s),
                 "max_position_difference": float(np.max(np.abs(flat.positions - res.positions)))},
        "iterations_saved": int(flat.relaxation.iterations - res.relaxation.iterations),
        "wall_time_saved_s": float(flat.relaxation.wall_time_s - res.relaxation.wall_time_s - prep),
    }


def _inverted(res: FormFindingResult, summary: dict, say) -> InvertedShell | None:
    """The inverted shell, its summary recorded; None (and the reason recorded) when it cannot be built."""
    try:
        inv = invert(res)
        summary["inverted"] = inv.summary()
    except ModelError as exc:
        inv = None
        summary["inverted"] = {"error": str(exc)}
        say(f"inversion skipped: {exc}")
    return inv


def solve_mra_case(params: dict, progress: Callable[[str], None] | None = None, *,
                   q0: np.ndarray | None = None, v0: np.ndarray | None = None, callback=None,
                   grid: QuadGrid | MeshNet | None = None) -> MraCase:
    """Form-find one case: start shape, relaxation, inversion, length statistics and control.

    Parameters
    ----------
    params : dict
        The case (see ``validation/mra/README.md``): ``geometry``, ``supports``,
        and optionally ``ropes``, ``masses``, ``loads``, ``solver``, ``start``,
        ``lengths``, ``output``.
    progress : callable, optional
        Receives progress lines.
    q0, v0 : ndarray, optional
        Start the relaxation from this state (and velocity) instead of the
        case's start shape: a checkpointed ``RelaxationProgress.q`` resumes a run.
    callback : callable, optional
        Also receives every ``RelaxationProgress`` of the form finding (for
        checkpoints); returning True stops it.
    grid : QuadGrid or MeshNet, optional
        The net's grid, when the caller has it (a mesh file it read);
        default the one ``params["geometry"]`` describes.
    """
    p = _merge(params)
    say = progress or (lambda msg: None)
    net = build_net(p, grid)
    options = _solver_options(p, progress)
    say(f"MRA case {p['name']!r}: {net.structure.n_nodes} nodes, {len(net.rope_edges)} ropes, "
        f"{len(net.supports)} suspension points, scheme {options['options'].scheme}")
    if q0 is None:
        q0, start_note = start_state(p, net, options, progress)
    else:
        start_note = {"type": "resumed"}
    res = form_find(net, q0, v0=v0, **_with_callback(options, progress, callback))
    say(res.relaxation.message)
    summary = {"name": p["name"], **res.summary()}
    summary["relaxation_wall_time_s"] = summary.pop("wall_time_s")
    summary["start"] = {**start_note, "relaxation_start": res.relaxation.start,
                        "iterations": int(res.relaxation.iterations),
                        "wall_time_s": float(res.relaxation.wall_time_s)}
    if p["start"]["compare_flat"] and start_note["type"] != "flat":
        summary["start"].update(_compare_flat(net, options, res, start_note, say))
    case = MraCase(summary, res, _inverted(res, summary, say), meshes=bool(p["output"]["meshes"]))
    L = p["lengths"]
    summary["rope_lengths"] = length_statistics(res.length, float(L["tolerance"]), L["target"])
    if L["control"]:
        lc = control_lengths(res, int(L["n_classes"]), float(L["tolerance"]), int(L["rounds"]), **{
            **options, "callback": None})
        summary["length_control"] = lc.summary()
        case.length_control = lc
        if case.meshes:
            try:
                case.length_control_inverted = invert(lc.result)
            except ModelError:
                pass
        say(f"length control: conforming ropes per round {lc.n_conforming}")
    return case
