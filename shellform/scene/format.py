"""The scene format: every table and key a scene may hold, with its type, unit, default and meaning.

The machinery that checks a value against a key and writes the reference is
:mod:`shellform.scene.schema`; :data:`SCENE` is what ``shellform schema`` prints and
``docs/scenes.md`` holds (``python docs/update_reference.py``).
"""

from __future__ import annotations

from ..solvers.continuation.options import ContinuationOptions
from .analysis_format import BUCKLING, DYNAMICS, INDENTATION, LENGTHS, RELAXATION, START_SHAPE, STUDY
from .schema import NONNEGATIVE as _NONNEG
from .schema import POSITIVE as _POS
from .schema import Key, Table

EFFECTS = ("axial", "rope", "rods", "loads", "gravity", "imperfection")
#: structured grids (rectangle, ellipse, disk, bspline) and gmsh planforms of any shape (polygon, curves, surface)
PLANFORMS = ("rectangle", "ellipse", "disk", "bspline", "polygon", "curves", "surface")
MESHED_PLANFORMS = ("polygon", "curves", "surface")
GEOMETRIES = PLANFORMS + ("hemisphere", "file")
ANALYSES = ("static", "continuation", "dynamics", "mra", "form_and_buckle", "indentation")
#: analyses that suit each source of geometry (the first is the default)
ANALYSES_OF = {
    "nodes": ("static", "continuation", "dynamics"),
    "file": ("static", "continuation", "dynamics", "mra", "form_and_buckle"),
    "planform": ("mra", "form_and_buckle"),
    "hemisphere": ("indentation",),
}
#: named node sets of a planform grid (:class:`~shellform.geometry.grids.QuadGrid`)
GRID_GROUPS = ("boundary", "corners", "south", "east", "north", "west", "sw", "se", "ne", "nw")
BAR_ROPE = ANALYSES_OF["nodes"]
FORM_FINDING = ANALYSES_OF["planform"]

#: divisions of a grid per side: far beyond any net that fits in memory is a typing error
_DIVISIONS = dict(minimum=1, maximum=10_000)
#: a rope's rest length beyond (1 + 10) times its reference length is a typing error
MAX_SLACK = 10.0
#: planform sizes: below a millimetre or beyond 1000 km is a typing error (and below 1e-8 m or beyond
#: 1e300 m the mesher's arithmetic fails)
_SIZE = dict(minimum=1.0e-3, maximum=1.0e6)

GEOMETRY = Table(
    discriminator="type",
    doc="Where the geometry comes from (instead of [nodes]). Planform grids (rectangle, ellipse, disk: gmsh "
        "structured quads; bspline: a quad grid on a NURBS surface) are hanging nets for form finding; "
        "'hemisphere' is the Chebyshev-net gridshell of discrete elastic rods; 'file' reads nodes and members "
        "from a mesh.",
    keys={
        "type": Key("str", "Geometry source.", choices=GEOMETRIES),
        "file": Key("str", "Mesh file read by meshio (.vtu, .msh, .obj, ...) or a Rhino file (.3dm), relative to "
                    "the scene file (type 'surface': a STEP, IGES or BREP file of surfaces, meshed by gmsh). "
                    "Line cells become members, and so do the edges of triangle and quad cells (each once). Of a Rhino file: curves are chains of lines, meshes triangles and quads, points nodes of "
                    "the named set of their layer; every layer is a named node set (docs/rhino.md).",
                    default=None, only=("file", "surface"), required_for=("file", "surface"), max_length=1000),
        "layers": Key("str_list", "Rhino file: read only the objects on these layers (full path 'parent::child' or "
                      "name; a parent takes its sub-layers). Default all.", default=None, only=("file",)),
        "segment_length": Key("float", "Rhino file: curves that are not polylines (arcs, NURBS) are divided into "
                              "equal segments at most this long (default: such curves are refused).", default=None,
                              unit="m", only=("file",), **_POS),
        "merge_tolerance": Key("float", "Rhino file: curve ends, mesh vertices and points closer than this are one "
                               "node (default the file's absolute tolerance).", default=None, unit="m",
                               only=("file",), **_POS),
        "length_x": Key("float", "Side of the rectangle along x.", default=None, unit="m", only=("rectangle",),
                        required_for=("rectangle",), **_SIZE),
        "length_y": Key("float", "Side of the rectangle along y.", default=None, unit="m", only=("rectangle",),
                        required_for=("rectangle",), **_SIZE),
        "n_i": Key("int", "Quads along x (rectangle) or along the surface's u direction (bspline).", default=None,
                   only=("rectangle", "bspline"), required_for=("rectangle", "bspline"), **_DIVISIONS),
        "n_j": Key("int", "Quads along y (rectangle) or along v (bspline).", default=None,
                   only=("rectangle", "bspline"), required_for=("rectangle", "bspline"), **_DIVISIONS),
        "origin": Key("vec3", "South-west corner of the rectangle.", default=[0.0, 0.0, 0.0], unit="m",
                      only=("rectangle",)),
        "a": Key("float", "Semi-axis of the ellipse along x.", default=None, unit="m", only=("ellipse",),
                 required_for=("ellipse",), **_SIZE),
        "b": Key("float", "Semi-axis of the ellipse along y.", default=None, unit="m", only=("ellipse",),
                 required_for=("ellipse",), **_SIZE),
        "center": Key("vec3", "Centre of the ellipse or disc.", default=[0.0, 0.0, 0.0], unit="m",
                      only=("ellipse", "disk")),
        "radius": Key("float", "Radius of the disc; of the hemisphere R (default 0.0382 m, the paper's "
                      "7.64 cm diameter).", default=None, unit="m", only=("disk", "hemisphere"),
                      required_for=("disk",), **_SIZE),
        "n": Key("int", "Quads per side of the mapped grid (ellipse, disk); rods per direction, odd "
                 "(hemisphere).", default=None, only=("ellipse", "disk", "hemisphere"),
                 required_for=("ellipse", "disk", "hemisphere"), **_DIVISIONS),
        "control_points": Key("surface_points", "Control points of the B-spline surface, nu x nv x 3; the grid "
                              "lies on the surface and the rope rest lengths come from it.", default=None, unit="m",
                              only=("bspline",), required_for=("bspline",)),
        "degree_u": Key("int", "Degree of the surface in u.", default=3, only=("bspline",), minimum=1),
        "degree_v": Key("int", "Degree of the surface in v.", default=3, only=("bspline",), minimum=1),
        "weights": Key("grid", "NURBS weights, nu x nv (default: all 1, a B-spline).", default=None, **_POS,
                       only=("bspline",)),
        "boundary": Key("points", "Corners of the planform's outer boundary, a closed polyline in order (the "
                        "closing segment implied; the loops lie in one plane).", default=None, unit="m",
                        only=("polygon",), required_for=("polygon",)),
        "holes": Table(
            array=True,
            doc="Holes of a 'polygon' planform ([[geometry.holes]]).",
            keys={"points": Key("points", "Corners of the hole, a closed polyline.", unit="m")},
        ),
        "curves": Table(
            array=True,
            doc="Boundary curves of a 'curves' planform ([[geometry.curves]]): B-splines or NURBS with clamped "
                "uniform knots; the curves of a loop run end to end, in order.",
            keys={
                "control_points": Key("points", "Control points of the curve.", unit="m"),
                "degree": Key("int", "Degree of the curve.", default=3, minimum=1, maximum=10),
                "weights": Key("float_or_list", "NURBS weights, one per control point (default all 1).",
                               default=None, **_POS),
                "loop": Key("int", "Loop of the curve: 0 the outer boundary, 1, 2, ... the holes.", default=0,
                            minimum=0, maximum=1000),
            },
        ),
        "edge_length": Key("float", "Target length of the mesh edges (polygon, curves, surface).", default=None,
                           unit="m", only=MESHED_PLANFORMS, required_for=MESHED_PLANFORMS, **_POS),
        "elements": Key("str", "Mesh of a gmsh planform: quads (transfinite, a structured grid, on a single "
                        "four-sided patch without holes; recombined unstructured elsewhere) or triangles.",
                        default="quads", only=MESHED_PLANFORMS, choices=("quads", "triangles")),
        "voronoi_length": Key("float", "Target rod edge length dl; each segment between joints gets round(h/dl) "
                              "edges.", default=1.0e-3, unit="m", only=("hemisphere",), **_POS),
    },
)

FRAME = Table(
    array=True,
    doc="Edge frames of a planform net (inline tables in supports.frames): every node on the straight grid line "
        "between two grid positions is a suspension point, lifted on a parabolic arch.",
    keys={
        "from": Key("position", "Grid position [i, j] where the frame starts."),
        "to": Key("position", "Grid position [i, j] where it ends (same i or same j)."),
        "rise": Key("float", "Rise of the arch at mid-frame.", default=0.0, unit="m"),
    },
)

SUPPORTS = Table(
    array=True,
    accept_single=True,
    doc="Supported nodes (suspension points of a hanging net) and their fixed translations. The node sets of "
        "one entry are combined; at least one is needed. A single [supports] table is read as one entry. The "
        "hemisphere needs none: its rod ends are pinned on the equator.",
    keys={
        "nodes": Key("index_list", "Node numbers.", default=None),
        "groups": Key("str_list", "Named node sets: of a planform grid 'boundary', 'corners', 'south', 'east', "
                      "'north', 'west', 'sw', 'se', 'ne', 'nw'; of a mesh file 'boundary' (nodes on edges of "
                      "exactly one face, or the ends of a line mesh) and the file's named point or cell sets.",
                      default=None),
        "positions": Key("positions", "Structured grid positions [i, j] of a planform (negative counts from the "
                         "end).", default=None),
        "frames": FRAME,
        "near": Key("points", "The node nearest to each of these points.", default=None, unit="m"),
        "box": Key("points", "The nodes inside this box, given by two opposite corners [[x0, y0, z0], [x1, y1, "
                   "z1]].", default=None, unit="m"),
        "curve": Key("points", "The nodes within `tolerance` of this polyline.", default=None, unit="m"),
        "tolerance": Key("float", "Distance from `curve`, and from `slide_curve` (default 1e-6 times the size of "
                         "the net, at least 1e-6 m).", default=None, unit="m", **_NONNEG),
        "z": Key("float", "Every node at this height (within z_tolerance).", default=None, unit="m"),
        "z_tolerance": Key("float", "Tolerance of z.", default=1.0e-6, unit="m", **_NONNEG),
        "dofs": Key("str", "Fixed components, any of the letters x, y, z; the others slide: 'z' on a horizontal "
                    "plane, 'yz' along a line parallel to x.", default="xyz"),
        "slide": Key("str", "Slide on a plane or along a line of any direction (`slide_direction`) through each "
                     "node, or along a curve (`slide_curve`: an arch, a ring beam), instead of fixing `dofs`: "
                     "held by a stiff spring across the plane, line or curve, whose force is the reaction.",
                     default=None, choices=("plane", "line", "curve")),
        "slide_direction": Key("vec3", "The plane's normal or the line's direction (any length).", default=None),
        "slide_curve": Key("points", "The curve of slide = 'curve': a smooth curve through these points (cubic "
                           "through four or more, closed when the last point repeats the first; a parabola "
                           "through three, a segment between two); default the support's `curve`. Every node "
                           "must lie on it within `tolerance`.", default=None, unit="m"),
        "slide_stiffness_ratio": Key("float", "The spring across the plane, line or curve as a multiple of the "
                                     "stiffest member at the node: the node leaves its plane, line or curve by "
                                     "its reaction over that stiffness.", default=1.0e2, **_POS),
    },
)


SCENE = Table(
    doc="A scene file.",
    keys={
        "title": Key("str", "Free text shown in the summary (and as the title of plots).", default=""),
        "name": Key("str", "Short name (runners of validation cases name their output folder after it): letters, "
                    "digits, '.', '_', '-' and '+', not starting with '.'.", default="", max_length=100,
                    pattern=(r"[A-Za-z0-9_+\-][A-Za-z0-9._+\-]*", "letters, digits, '.', '_', '-' or '+', not "
                             "starting with '.' (it names a folder)")),
        "description": Key("str", "Free text.", default="", max_length=5000),
        "nodes": Table(
            doc="Node coordinates of the reference configuration (a structure given node by node; instead of "
                "[geometry]).",
            keys={"coordinates": Key("points", "Reference coordinates, one [x, y, z] per node.", unit="m")},
        ),
        "geometry": GEOMETRY,
        "members": Table(
            array=True,
            doc="Groups of two-node members sharing one law (with [nodes] or a mesh file).",
            keys={
                "name": Key("str", "Group name (unique).", default=""),
                "kind": Key("str", "Member law.", choices=("bar", "rope")),
                "connectivity": Key("pairs", "End nodes of each member (required with [nodes]; with a mesh file "
                                    "the default is the edges of the cells listed in `cells`).", default=None),
                "cells": Key("str_list", "Mesh file: members are the edges of cells of these types (default all), "
                             "less edges an earlier group took.", default=None,
                             choices=("line", "triangle", "quad")),
                "EA": Key("float_or_list", "Axial stiffness, one value or one per member.", unit="N", **_POS),
                "mass_per_length": Key("float_or_list", "Linear density for self-weight and inertia.", default=0.0,
                                       unit="kg/m", **_NONNEG),
                "slack": Key("float_or_list", "Rope slack coefficient sc: rest length = (1 + sc) x reference "
                             "length. Ropes only.", default=0.0, minimum=-1.0, exclusive_minimum=True,
                             maximum=MAX_SLACK),
                "rest_length": Key("float_or_list", "Unstressed length; overrides the reference length and "
                                   "slack (default: from them).", default=None, unit="m", **_POS),
            },
        ),
        "ropes": Table(
            doc="The ropes of a planform net (form finding): every grid edge is a tension-only rope.",
            keys={
                "slack": Key("float_or_list", "Slack coefficient sc: rest length = (1 + sc) x planform edge length; "
                             "one number, or [sc_i, sc_j] for the two families of grid lines.", default=0.0,
                             minimum=-1.0, exclusive_minimum=True, maximum=MAX_SLACK),
                "EA": Key("float", "Axial stiffness (default stiffness_ratio x the weight of the net).", default=None,
                          unit="N", **_POS),
                "stiffness_ratio": Key("float", "EA over the net's weight when EA is not given.", default=1.0e4,
                                       **_POS),
                "mass_per_length": Key("float", "Rope mass, lumped half to each end node.", default=1.0,
                                       unit="kg/m", **_NONNEG),
                "strain_limit": Key("float", "Net ropes strained beyond this at rest are named in a warning and "
                                    "counted in the summary (n_overstretched_ropes): the shape there depends on EA.",
                                    default=0.01, **_POS),
            },
        ),
        "cables": Table(
            array=True,
            doc="Edge cables of a hanging net (form finding): the boundary edges whose two ends are among the "
                "nodes an entry names (as [[supports]] names them) are a rope group of their own, with its own "
                "axial stiffness, slack and mass, instead of net ropes.",
            keys={
                "name": Key("str", "Group name (default cable_0, cable_1, ...).", default=""),
                "nodes": Key("index_list", "Node numbers.", default=None),
                "groups": Key("str_list", "Named node sets of the net (see [[supports]] groups).", default=None),
                "near": Key("points", "The node nearest to each of these points.", default=None, unit="m"),
                "box": Key("points", "The nodes inside this box (two opposite corners).", default=None, unit="m"),
                "curve": Key("points", "The nodes within `tolerance` of this polyline.", default=None, unit="m"),
                "tolerance": Key("float", "Distance from `curve`.", default=None, unit="m", **_NONNEG),
                "EA": Key("float", "Axial stiffness of the cable.", unit="N", **_POS),
                "slack": Key("float", "Slack coefficient: rest length = (1 + slack) x planform edge length.",
                             default=0.0, minimum=-1.0, exclusive_minimum=True, maximum=MAX_SLACK),
                "mass_per_length": Key("float", "Cable mass (default the ropes').", default=None, unit="kg/m",
                                       **_NONNEG),
            },
        ),
        "rods": Table(
            doc="Discrete elastic rods: their section and material, where they run and how they meet. The "
                "hemisphere's rods (defaults: the paper's 1 mm radius, E = 100 GPa, G = E/3, 1000 kg/m^3) and those "
                "of the gridshell built on a found form (defaults: 20 mm radius, E = 210 GPa, G = E/2.6, weightless: "
                "the net's weight is the load) are solid circles; the rods of a [nodes] or mesh-file scene (static, "
                "continuation, dynamics) run along [[rods.lines]] or the mesh's edge chains (layout), with any "
                "section. A rod's section lies in the plane of its material directors m1, m2; EI1 is the stiffness "
                "of the rod turning towards m1, EI2 towards m2.",
            keys={
                "E": Key("float", "Young's modulus (default above; required for the rods of a [nodes] or mesh-file "
                         "scene).", default=None, unit="Pa", **_POS),
                "G": Key("float", "Shear modulus (default above; E/2.6 for the rods of a [nodes] or mesh-file "
                         "scene).", default=None, unit="Pa", **_POS),
                "density": Key("float", "Density of the rods (default above; 0 for the rods of a [nodes] or "
                               "mesh-file scene): their self-weight under [gravity] and their inertia.", default=None,
                               unit="kg/m^3", **_NONNEG),
                "section": Key("str", "Shape of the section: solid circle (radius), tube (radius, thickness) or "
                               "rectangle (depth along m1, width along m2). Its area, second moments, torsion "
                               "constant (Saint-Venant's series for the rectangle) and extreme fibres are computed; "
                               "the rods' results then include max_stress.", default="circle",
                               choices=("circle", "hollow_circle", "rectangle")),
                "radius": Key("float", "Radius of a circle, outer radius of a tube (default above).", default=None,
                              unit="m", **_POS),
                "thickness": Key("float", "Wall thickness of a tube.", default=None, unit="m", **_POS),
                "depth": Key("float", "Rectangle: side along m1 (with orientation 'surface', across the surface: the "
                             "thickness of a lath lying on it).", default=None, unit="m", **_POS),
                "width": Key("float", "Rectangle: side along m2 (in the surface).", default=None, unit="m", **_POS),
                "orientation": Key("str", "First director m1 of every rod edge: the surface normal of the mesh's "
                                   "faces at the edge ('surface', the default where the mesh has faces), or the "
                                   "vertical projected perpendicular to a rod's first edge (x if it is vertical), "
                                   "carried along the rod by parallel transport ('vertical').",
                                   default=None, choices=("surface", "vertical")),
                "layout": Key("str", "Where the rods of a [nodes] or mesh-file scene run: along [[rods.lines]] "
                              "('lines', the default when they are given) or along the edge chains of the mesh's "
                              "quads and lines ('mesh_lines': a chain goes straight on through every node where it "
                              "has exactly one edge that shares no face with it, and ends elsewhere).",
                              default=None, choices=("lines", "mesh_lines")),
                "lines": Table(
                    array=True,
                    doc="One rod each, through the given nodes in order (a [nodes] or mesh-file scene).",
                    keys={
                        "nodes": Key("index_list", "Node numbers along the rod (at least 2; 3 when closed)."),
                        "closed": Key("bool", "The last node joins back to the first (a ring).", default=False),
                        "name": Key("str", "Rod name (default rod<k>).", default=""),
                    },
                ),
                "rest_shape": Key("str", "Rods straight and untwisted when unstressed (bent into the geometry; "
                                  "form_and_buckle relaxes that prestress first, a rod scene starts from it) or "
                                  "stress-free in the geometry as found or given. Default: straight for "
                                  "form_and_buckle, found for a rod scene.", default=None,
                                  choices=("straight", "found")),
                "joints": Key("str", "Where rods cross at a node: tied by a penalty spring between two nodes (the "
                              "paper's Eq. 3; of a [nodes] or mesh-file scene, every rod after the first through "
                              "a node gets its own copy of it, tied to the first), or sharing one node. Default: "
                              "penalty for the hemisphere, shared for a rod scene.", default=None,
                              choices=("penalty", "shared")),
                "joint_stiffness_ratio": Key("float", "Penalty stiffness over the rods' axial stiffness at the "
                                             "joint (default 1e3).", default=1.0e3, **_POS),
                "joint_rotational_stiffness": Key("float", "Rotational spring on the angle between the two rods "
                                                  "at every crossing (a shared node or a penalty joint): the "
                                                  "scissor stiffness of a tightened or braced joint, stress free at "
                                                  "the angle of the scene's geometry; 0 lets the rods turn freely.",
                                                  default=0.0, unit="N m/rad", **_NONNEG),
                "support_rotation": Key("str", "Rods at a supported node of a [nodes] or mesh-file scene: "
                                        "'free' to turn about it (the twist of their edges that touch it held, so "
                                        "that they cannot spin), or 'clamped' (both nodes of every rod edge that "
                                        "touches a support fixed like the support, and its twist held).",
                                        default="free", choices=("free", "clamped")),
            },
        ),
        "masses": Table(
            doc="Extra point masses.",
            keys={"node_mass": Key("float", "Point mass at every node.", default=0.0, unit="kg", **_NONNEG)},
        ),
        "supports": SUPPORTS,
        "prescribed": Table(
            array=True,
            doc="Prescribed motion: displacement = parameter x direction.",
            keys={
                "nodes": Key("index_list", "Driven nodes."),
                "direction": Key("vec3", "Displacement per unit parameter.", unit="m"),
            },
        ),
        "loads": Table(
            array=True,
            doc="Nodal forces.",
            keys={
                "nodes": Key("index_list", "Loaded nodes."),
                "force": Key("vec3", "Force on each listed node.", unit="N"),
                "scaled": Key("bool", "Multiplied by the load factor (else a dead load).", default=True),
            },
        ),
        "gravity": Table(
            doc="Self-weight of member and point masses. A hanging net always has it (default g shown).",
            keys={
                "g": Key("vec3", "Gravitational acceleration.", default=[0.0, 0.0, -9.81], unit="m/s^2"),
                "scaled": Key("bool", "Multiplied by the load factor (else a dead load).", default=False),
            },
        ),
        "imperfection": Table(
            discriminator="type",
            doc="An imperfection that breaks the symmetry of a perfect structure. 'random' and 'mode' move the "
                "nodes of the stress-free geometry (free DOFs only; members get their rest lengths from the "
                "moved geometry); 'forces' adds small random dead forces at the free nodes (the 'imperfection' "
                "effect; the hemisphere's only kind).",
            keys={
                "type": Key("str", "random: every free node moved by a random vector; mode: the nodes moved along "
                            "the lowest eigenmode of the tangent stiffness; forces: random dead forces.",
                            choices=("random", "mode", "forces")),
                "amplitude": Key("float", "Largest node movement (random, mode) [m], or norm of all the forces "
                                 "together (forces) [N]. For mode its sign picks the direction (the mode is "
                                 "normalised with its largest component positive); otherwise it is > 0.",
                                 unit="m or N"),
                "seed": Key("int", "Seed of the random numbers.", default=0, minimum=0, only=("random", "forces")),
                "load_factor": Key("float", "mode: the tangent at the equilibrium under this load factor (default: "
                                   "the tangent at the start state).", default=None, only=("mode",)),
            },
        ),
        "study": STUDY,
        "effects": Table(
            doc="The physical effects to simulate; nothing else is evaluated (bar and rope structures).",
            keys={
                "include": Key("str_list", "Effects in the system. Default: those the scene's members, loads, "
                               "gravity and imperfection call for.", default=None, choices=EFFECTS),
            },
        ),
        "analysis": Table(
            fill_defaults=True,
            doc="What to compute. The settings of each analysis are in its own sub-table.",
            keys={
                "type": Key("str", "Analysis (default: static for [nodes] and mesh files, mra for planform grids, "
                            "form_and_buckle when [analysis.buckling] is given, indentation for the hemisphere).",
                            default=None, choices=ANALYSES),
                "load_factor": Key("float", "Factor on the scaled loads (static, dynamics; the fixed factor of a "
                                   "displacement-controlled path).", default=1.0),
                "prescribed": Key("float", "Prescribed-displacement parameter.", default=0.0),
                "start": Key("points", "Starting coordinates (default: the reference).", default=None, unit="m"),
                "merit": Key("str", "Static line-search merit: energy finds stable equilibria, residual any.",
                             default="energy", choices=("energy", "residual")),
                "max_iterations": Key("int", "Static Newton iterations before giving up.", default=100, minimum=1),
                "rtol": Key("float", "Static/continuation residual tolerance relative to the load/reaction norm.",
                            default=1e-10, **_POS),
                "linear_solver": Key("str", "Linear solver (static, dynamics).", default="direct",
                                     choices=("direct", "amg", "auto")),
                "continuation": Table(
                    fill_defaults=True,
                    doc="Arc-length continuation (analysis 'continuation'). The path starts from equilibrium at "
                        "parameter 0 (the other parameter at its [analysis] value).",
                    keys={
                        "control": Key("str", "Path parameter: the load factor or the prescribed-displacement "
                                       "parameter.", default="load", choices=("load", "displacement")),
                        "max_steps": Key("int", "Accepted steps before stopping.", default=200, minimum=1),
                        "parameter_min": Key("float", "Stop when the parameter falls below this (default: no bound).",
                                             default=None),
                        "parameter_max": Key("float", "Stop when the parameter exceeds this (default: no bound).",
                                             default=None),
                        "initial_increment": Key("float", "First parameter increment (default: 1/20 of the "
                                                 "distance to the bound).", default=None),
                        "max_displacement": Key("float", "Stop when a free DOF moves further than this (default: no "
                                                "bound).",
                                                default=None, unit="m", **_POS),
                        "constraint": Key("str", "Arc-length constraint.", default="spherical",
                                          choices=("spherical", "cylindrical")),
                        "stability": Key("bool", "Count negative eigenvalues of the tangent at every point.",
                                         default=True),
                        "eigenvalue_column": Key("bool", "Also write the eigenvalue of the tangent nearest zero at "
                                                 "every point (column 'eigenvalue' of path.csv; a Lanczos run "
                                                 "per point).", default=False),
                        "critical_rtol": Key("float", "Relative tolerance to which the load (the path parameter) "
                                             "of every limit and bifurcation point is located.",
                                             default=ContinuationOptions.critical_rtol, minimum=1e-12, maximum=0.1),
                        "on_bifurcation": Key("str", "At a bifurcation: stay on the primary branch, follow the "
                                              "secondary one, or stop.", default="continue",
                                              choices=("continue", "switch", "stop")),
                        "branch_side": Key("int", "Which half of the secondary branch (+1 or -1).", default=1),
                        "monitor_node": Key("int", "Node whose displacement is the curve's abscissa (default: "
                                            "the most loaded or driven DOF).", default=None, minimum=0),
                        "monitor_component": Key("str", "Component of monitor_node.", default="z",
                                                 choices=("x", "y", "z")),
                        "checkpoint_every": Key("int", "Write a checkpoint every this many steps.", default=10,
                                                minimum=1),
                    },
                ),
                "relaxation": RELAXATION,
                "start_shape": START_SHAPE,
                "lengths": LENGTHS,
                "buckling": BUCKLING,
                "indentation": INDENTATION,
                "dynamics": DYNAMICS,
            },
        ),
        "output": Table(
            fill_defaults=True,
            doc="What to write besides summary.json.",
            keys={
                "formats": Key("str_list", "The final state in each format (state.vtu, state.3dm, ...; 3dm: Rhino, "
                               "needs the rhino extra; compas: state.compas.json, a COMPAS graph with the member "
                               "results on its edges). Paths and time series are XDMF whatever this says. Form "
                               "finding writes its VTU meshes (see meshes) and, with '3dm', form.3dm.",
                               default=["vtu", "xdmf"], choices=("vtu", "vtk", "xdmf", "3dm", "compas")),
                "meshes": Key("bool", "Form finding: write the hanging net, the inverted net and the inverted "
                              "shell surface (hanging.vtu, inverted.vtu, inverted_shell.vtu).", default=True),
            },
        ),
    },
)
