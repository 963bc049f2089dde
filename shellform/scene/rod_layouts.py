"""The rods of a ``[nodes]`` or mesh-file scene: where they run, their section, joints and supports.

A scene's ``[rods]`` table gives the rods' section and material
(:func:`scene_section`) and, for a structure given node by node or read from
a mesh, where they run (:func:`rod_layout`): along ``[[rods.lines]]`` or
along the mesh's edge chains (:func:`shellform.rods.mesh_lines.edge_chains`).
With penalty joints every rod after the first through a node gets its own
copy of that node (appended after the scene's nodes, so node numbers of
supports and loads keep their meaning), tied to the first by a spring.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ModelError, SceneError
from ..rods.mesh_lines import chain_directors, edge_chains, vertex_normals
from ..rods.section import RestShape, RodSection, section_of
from ..geometry.sections import hollow_circle, rectangle, solid_circle
from .error_keys import scene_error_at

#: the shape keys of each section
SECTION_KEYS = {"circle": ("radius",), "hollow_circle": ("radius", "thickness"), "rectangle": ("depth", "width")}
#: shear modulus over Young's modulus when G is not given (an isotropic material with Poisson's ratio 0.3)
G_OVER_E = 1.0 / 2.6


def has_rods(scene: dict) -> bool:
    """Whether a ``[nodes]`` or mesh-file scene has rods."""
    return scene.get("source") in ("nodes", "file") and scene.get("rods") is not None


def scene_section(rods: dict, defaults: dict | None = None) -> RodSection:
    """The section of ``[rods]``: its shape from the section's keys, in the material ``E``, ``G``, ``density``.

    ``defaults`` fills keys the table leaves open (``E``, ``G``, ``radius``,
    ``density``); without one, ``E`` and the shape's dimensions are required,
    ``G`` is ``E / 2.6`` and the density 0.
    """
    defaults = defaults or {}

    def value(key):
        v = rods.get(key)
        return defaults.get(key) if v is None else v

    kind = rods.get("section") or "circle"
    for key in SECTION_KEYS[kind]:
        if value(key) is None:
            raise SceneError(f"rods.{key}", f"this key is required for section = {kind!r}")
    for kinds, key in (((k for k in SECTION_KEYS if key not in SECTION_KEYS[k]), key)
                       for key in ("thickness", "depth", "width")):
        if rods.get(key) is not None and kind in set(kinds):
            raise SceneError(f"rods.{key}", f"does not apply to section = {kind!r}; it applies to "
                             + ", ".join(repr(k) for k in SECTION_KEYS if key in SECTION_KEYS[k]))
    if value("E") is None:
        raise SceneError("rods.E", "this key is required for rods (Young's modulus)")
    E = value("E")
    G = value("G") if value("G") is not None else G_OVER_E * E
    density = value("density") if value("density") is not None else 0.0
    with scene_error_at("rods"):
        if kind == "circle":
            shape = solid_circle(value("radius"))
        elif kind == "hollow_circle":
            if value("thickness") >= value("radius"):
                raise SceneError("rods.thickness", f"got {value('thickness')!r}; expected less than the radius "
                                 f"{value('radius')!r} (a solid circle is section = 'circle')")
            shape = hollow_circle(value("radius"), value("thickness"))
        else:
            shape = rectangle(value("depth"), value("width"))
        return section_of(shape, E, G, density)


@dataclass(frozen=True)
class RodLayout:
    """Where the rods of a scene run.

    Attributes
    ----------
    chains : list of (ndarray, bool)
        Node numbers of every rod (copies included) and whether it is closed.
    names : list of str
    copies : ndarray (c,)
        The scene node each appended copy stands for (copy ``k`` is node
        ``n_scene + k``).
    pairs : ndarray (c, 2)
        Penalty joints: scene node, its copy.
    directors : list of ndarray (m_k, 3) or None
        First director of every edge of every rod (orientation 'surface'),
        or None (orientation 'vertical': the vertical projected perpendicular
        to a rod's first edge, carried along it by parallel transport).
    """

    chains: list
    names: list
    copies: np.ndarray
    pairs: np.ndarray
    directors: list | None


def _scene_chains(scene: dict, n: int) -> tuple[list, list]:
    rods = scene["rods"]
    layout = rods["layout"] or ("lines" if rods["lines"] else None)
    if layout is None:
        raise SceneError("rods.layout", "the rods of a [nodes] or mesh-file scene need [[rods.lines]] or "
                         "layout = 'mesh_lines'")
    if layout == "lines":
        if not rods["lines"]:
            raise SceneError("rods.lines", "layout 'lines' needs at least one [[rods.lines]] entry")
        chains, names = [], []
        for k, line in enumerate(rods["lines"]):
            nodes = np.atleast_1d(np.asarray(line["nodes"], dtype=np.int64))
            bad = np.flatnonzero((nodes < 0) | (nodes >= n))
            if bad.size:
                raise SceneError(f"rods.lines[{k}].nodes", f"node {int(nodes[bad[0]])} is out of range (the scene "
                                 f"has {n} nodes)")
            chains.append((nodes, bool(line["closed"])))
            names.append(line["name"] or f"rod{k}")
        return chains, names
    if scene["source"] != "file":
        raise SceneError("rods.layout", "'mesh_lines' follows the edges of a mesh file; this scene has [nodes]")
    if rods["lines"]:
        raise SceneError("rods.lines", "give [[rods.lines]] or layout = 'mesh_lines', not both")
    mesh = scene["mesh"]
    if "triangle" in mesh.cells:
        raise SceneError("rods.layout", "'mesh_lines' follows quads and lines; this mesh has triangles, whose "
                         "edges make no straight chains: give [[rods.lines]]")
    chains = edge_chains(n, mesh.cells.get("quad"), mesh.cells.get("line"))
    return chains, [f"rod{k}" for k in range(len(chains))]


def rod_layout(scene: dict, nodes: np.ndarray) -> RodLayout:
    """The rods of a validated rod scene over its ``nodes`` (the scene's own, before any copy)."""
    n = len(nodes)
    chains, names = _scene_chains(scene, n)
    rods = scene["rods"]
    orientation = rods["orientation"]
    faces = [] if scene["source"] != "file" else [
        scene["mesh"].cells[f] for f in ("triangle", "quad") if f in scene["mesh"].cells]
    if orientation is None:
        orientation = "surface" if faces else "vertical"
    if orientation == "surface" and not faces:
        raise SceneError("rods.orientation", "'surface' takes the normal of the mesh's faces; this scene has none: "
                         "use 'vertical'")
    directors = None
    if orientation == "surface":
        normals = vertex_normals(np.asarray(nodes, dtype=float), faces)
        lonely = [k for k, (c, _) in enumerate(chains) if np.any(np.linalg.norm(normals[c], axis=1) == 0)]
        if lonely:
            raise SceneError("rods.orientation", f"rod {names[lonely[0]]!r} has nodes on no face, so no surface "
                             "normal: use 'vertical'")
        directors = [chain_directors(nodes, c, closed, normals) for c, closed in chains]
    joints = rods["joints"] or "shared"
    copies, pairs = [], []
    if joints == "penalty":
        owner = np.full(n, -1)
        out = []
        for k, (c, closed) in enumerate(chains):
            c = c.copy()
            for i, node in enumerate(c):
                if owner[node] == -1:
                    owner[node] = k
                elif owner[node] != k:
                    pairs.append((node, n + len(copies)))
                    c[i] = n + len(copies)
                    copies.append(node)
            out.append((c, closed))
        chains = out
    return RodLayout(chains=chains, names=names, copies=np.array(copies, dtype=np.int64),
                     pairs=np.array(pairs, dtype=np.int64).reshape(-1, 2), directors=directors)


def add_scene_rods(scene: dict, structure, layout: RodLayout):
    """The rods of ``layout`` on ``structure`` (whose nodes include the copies): a RodNetwork.

    Supported nodes hold the twist of the rod edges that touch them (and,
    with ``support_rotation = 'clamped'``, both nodes of those edges in the
    support's directions). Call after the supports are fixed.
    """
    from ..rods.network import RodNetwork

    rods = scene["rods"]
    section = scene_section(rods)
    straight = (rods["rest_shape"] or "found") == "straight"
    network = RodNetwork(structure)
    for k, ((chain, closed), name) in enumerate(zip(layout.chains, layout.names)):
        # 'vertical': the first edge's director, carried along the rod by parallel transport
        director = None if layout.directors is None else layout.directors[k]
        rest = RestShape(natural_curvature="straight" if straight else "rest", director=director)
        where = f"rods.lines[{k}]" if rods["lines"] else "rods"
        try:
            network.add_rod(chain, section, rest, closed=closed, name=name)
        except ModelError as exc:
            raise SceneError(where, str(exc)) from None
    if len(layout.pairs):
        network.add_joints(layout.pairs, stiffness_ratio=rods["joint_stiffness_ratio"])
    network.hold_crossing_angles(rods["joint_rotational_stiffness"])
    network.anchor_held_twists()
    _hold_rods_at_supports(structure, network, rods["support_rotation"], layout)
    return network


def _hold_rods_at_supports(structure, network, rotation: str, layout: RodLayout) -> None:
    """Twist held on rod edges touching a supported node (or a joint copy of one); 'clamped' also fixes
    both nodes of those edges in the support's directions."""
    n = structure.n_nodes
    fixed = structure.constrained_mask[: 3 * n].reshape(n, 3).copy()
    n_scene = n - len(layout.copies)
    fixed[n_scene:] |= fixed[layout.copies]
    supported = fixed.any(axis=1)
    for rod in network.rods:
        a = rod.nodes
        b = np.roll(a, -1) if rod.closed else a[1:]
        a = a[: len(b)]
        touch = supported[a] | supported[b]
        structure.fix_dofs(rod.twist_dofs[touch])
        if rotation == "clamped":
            for k in np.flatnonzero(touch):
                dirs = fixed[a[k]] | fixed[b[k]]
                structure.fix([a[k], b[k]], "".join(c for c, f in zip("xyz", dirs) if f))
