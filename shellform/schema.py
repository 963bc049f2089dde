"""Scene schema: every key, its type, unit, default and meaning.

:class:`Key` and :class:`Table` describe a TOML table; :func:`check_table`
validates data against one (errors name the key, the value and what is
allowed) and :func:`reference` writes the Markdown reference. :data:`SCENE` is
the scene format: ``shellform schema`` prints it and ``docs/scenes.md`` holds
it (``python docs/update_reference.py``).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Any

import numpy as np

from .errors import SceneError
from .mra.formfind import COARSE_START_NODES
from .solvers.relaxation.options import Refinements, RelaxationOptions

_REQUIRED = object()


@dataclass(frozen=True)
class Key:
    """One scalar or array entry of a scene table."""

    kind: str  # see KINDS
    doc: str
    default: Any = _REQUIRED
    unit: str = ""
    choices: tuple = ()
    minimum: float | None = None
    exclusive_minimum: bool = False
    maximum: float | None = None
    #: values of the table's discriminator (its ``type``) for which the key applies (empty: all)
    only: tuple = ()
    #: values of the discriminator for which the key must be given
    required_for: tuple = ()
    #: largest magnitude of a number (default: by unit, :data:`UNIT_BOUNDS`, else :data:`LIMITS`)
    magnitude: float | None = None
    #: most characters of a string (default ``LIMITS["text"]``)
    max_length: int | None = None
    #: a string must match this regular expression (and its description)
    pattern: tuple = ()

    @property
    def required(self) -> bool:
        return self.default is _REQUIRED

    def bound(self, integer: bool = False) -> float:
        """The largest magnitude a number of this key may have."""
        if self.magnitude is not None:
            return self.magnitude
        if integer or self.kind in ("int", "pairs", "positions", "position", "index_list"):
            return LIMITS["integer"]
        return UNIT_BOUNDS.get(self.unit, LIMITS["number"])


@dataclass(frozen=True)
class Table:
    """A TOML table (``[name]``) or, with ``array=True``, an array of tables (``[[name]]``)."""

    keys: dict
    doc: str
    array: bool = False
    optional: bool = True
    #: when absent, behave as if present with every default (else None)
    fill_defaults: bool = False
    #: name of the key whose value selects which other keys apply (see ``Key.only``)
    discriminator: str | None = None
    #: an array of tables that also takes a single table (``[name]`` for ``[[name]]``)
    accept_single: bool = False


#: limits of a scene: beyond them a value is a typing error or a unit off, and the arithmetic (squares of
#: lengths, products of stiffness and strain) or the memory of the run would fail long before a result
LIMITS = {
    "text": 200,            # characters of a string (title, name, ...) unless its key says otherwise
    "list": 100,            # entries of a list of strings
    "items": 2_000_000,     # entries along one dimension of an array (nodes, members, points)
    "integer": 10**9,       # magnitude of an integer (counts, node numbers, grid positions)
    "number": 1.0e12,       # magnitude of a dimensionless number unless its key says otherwise
    "scene_bytes": 256 * 2**20,  # size of a scene file
}
#: largest magnitude of a number of each unit unless its key says otherwise
UNIT_BOUNDS = {
    "m": 1.0e6, "m or N": 1.0e6, "m/s": 1.0e6, "m/s^2": 1.0e6,
    "N": 1.0e12, "Pa": 1.0e13,
    "kg": 1.0e12, "kg/m": 1.0e9, "kg/m^3": 1.0e6,
    "s": 1.0e9, "1/s": 1.0e9,
}


def short(value, limit: int = 60) -> str:
    """``repr(value)`` cut to about ``limit`` characters, safe for any nesting depth and size."""

    def r(v, depth):
        if isinstance(v, np.ndarray):
            v = v.ravel()[:9].tolist() + (["..."] if v.size > 9 else [])
        if isinstance(v, (list, tuple)):
            if depth > 3:
                return "[...]"
            inner = [r(x, depth + 1) for x in v[:8]] + (["..."] if len(v) > 8 else [])
            return "[" + ", ".join(inner) + "]"
        if isinstance(v, dict):
            if depth > 3:
                return "{...}"
            items = list(v.items())
            inner = [f"{r(k, depth + 1)}: {r(x, depth + 1)}" for k, x in items[:6]] + (["..."] if len(items) > 6
                                                                                        else [])
            return "{" + ", ".join(inner) + "}"
        if isinstance(v, str):
            return repr(v[: limit + 1]) if len(v) <= limit else repr(v[:limit]) + "..."
        if isinstance(v, int) and not isinstance(v, bool) and abs(v) >= 10**30:
            return f"{float(v):.3e}" if abs(v) < 10**308 else ("-" if v < 0 else "") + "an integer beyond 1e308"
        if isinstance(v, str) or v is None or isinstance(v, (bool, int, float)):
            return repr(v)
        return f"<{type(v).__name__}>"

    shown = r(value, 0)
    return shown if len(shown) <= limit else shown[: limit - 3] + "..."


def _fail(path, value, allowed):
    raise SceneError(path, f"got {short(value)}; expected {allowed}")


def _bound_text(bound: float, unit: str) -> str:
    return f"{bound:.0e}".replace("e+0", "e").replace("e+", "e") + (f" {unit}" if unit else "")


def _number(path, value, key: Key, integer=False):
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        _fail(path, value, "an integer" if integer else "a number")
    if integer and not isinstance(value, int):
        _fail(path, value, "an integer")
    if isinstance(value, float) and not np.isfinite(value):
        _fail(path, value, "a finite number")
    _check_range(path, value, key)
    bound = key.bound(integer)
    if abs(value) > bound:
        _fail(path, value, f"a number of magnitude <= {_bound_text(bound, key.unit)}")
    return int(value) if integer else float(value)


def _check_range(path, value, key: Key):
    if key.minimum is not None:
        if value < key.minimum or (key.exclusive_minimum and value == key.minimum):
            rel = ">" if key.exclusive_minimum else ">="
            _fail(path, value, f"a number {rel} {key.minimum}")
    if key.maximum is not None and value > key.maximum:
        _fail(path, value, f"a number <= {key.maximum}")


def _at(path: str, index) -> str:
    return f"{path}{list(index)}" if len(index) else path


def _numbers(path, value, shape_doc, ndim, key: Key, integer=False, width=None) -> np.ndarray:
    """A nested list of ``ndim`` levels of numbers as an array, every entry checked.

    Refuses what NumPy would coerce (booleans, numeric strings), ragged rows,
    deeper nesting, rows of other than ``width`` numbers, non-finite values,
    values out of the key's bounds and more entries per dimension than
    ``LIMITS["items"]``; the error names the entry (``key[i, j]``) and what is
    allowed.
    """
    fast = _well_formed(value, ndim, key, integer, width)
    if fast is not None:
        return fast
    want = "an integer" if integer else "a number"
    bound = key.bound(integer)
    shape: list[int] = []
    flat: list = []

    def where(index):  # which coordinate of which node a point entry is
        return f" (coordinate {'xyz'[index[1]]} of node {index[0]})" if key.kind == "points" else ""

    def walk(v, level, index):
        if level == ndim:
            if isinstance(v, bool) or not isinstance(v, (int, float)) or (integer and not isinstance(v, int)):
                raise SceneError(_at(path, index), f"got {short(v)}; expected {want} ({shape_doc})")
            if isinstance(v, float) and not np.isfinite(v):
                raise SceneError(_at(path, index), f"got {v!r}: the value is not finite; expected {want}"
                                 + where(index))
            _check_range(_at(path, index), v, key)
            if abs(v) > bound:
                raise SceneError(_at(path, index), f"got {short(v)}; expected {want} of magnitude <= "
                                 f"{_bound_text(bound, key.unit)}" + where(index))
            flat.append(v)
            return
        if not isinstance(v, list):
            _fail(_at(path, index), v, shape_doc if not index else f"a list ({shape_doc})")
        if len(v) > LIMITS["items"]:
            raise SceneError(_at(path, index), f"has {len(v):,} entries; at most {LIMITS['items']:,} are allowed")
        if width is not None and level == ndim - 1 and len(v) != width:
            raise SceneError(path, f"entry {list(index)} has {len(v)} numbers; expected {shape_doc}")
        if len(shape) == level:
            shape.append(len(v))
        elif shape[level] != len(v):
            raise SceneError(path, f"entry {list(index)} has {len(v)} entries where the entries before have "
                             f"{shape[level]}; expected {shape_doc}")
        for i, x in enumerate(v):
            walk(x, level + 1, index + (i,))

    walk(value, 0, ())
    if len(shape) < ndim:  # an empty list somewhere above the numbers
        shape += [0] * (ndim - len(shape))
    return np.array(flat, dtype=np.int64 if integer else float).reshape(shape)


def _well_formed(value, ndim, key: Key, integer, width) -> np.ndarray | None:
    """The array of a list (or list of rows) of plain numbers that passes every check; None for anything
    else, which :func:`_numbers` then walks entry by entry to name what is wrong (the quick way for large
    arrays: the walk takes seconds per million entries)."""
    if type(value) is not list or not value or ndim > 2 or len(value) > LIMITS["items"]:
        return None
    kinds = (int,) if integer else (int, float)
    if ndim == 2:
        w = width if width is not None else (len(value[0]) if value and type(value[0]) is list else -1)
        if not all(type(row) is list and len(row) == w for row in value):
            return None
        flat = [x for row in value for x in row]
        shape = (len(value), w)
    else:
        flat, shape = value, (len(value),)
    if not all(type(x) in kinds for x in flat):
        return None
    try:
        arr = np.array(flat, dtype=np.int64 if integer else float).reshape(shape)
    except OverflowError:  # an integer beyond 64 bits
        return None
    if arr.size and not integer and not np.all(np.isfinite(arr)):
        return None
    if arr.size and (np.abs(arr).max() > key.bound(integer)
                     or key.minimum is not None and (arr.min() < key.minimum or key.exclusive_minimum
                                                     and arr.min() == key.minimum)
                     or key.maximum is not None and arr.max() > key.maximum):
        return None
    return arr


def _array(path, value, shape_doc, key: Key, ncol=None, integer=False, ndim=None):
    arr = _numbers(path, value, shape_doc, ndim or (2 if ncol is not None else 1), key, integer, ncol)
    if ncol is not None and (arr.shape[1] != ncol or arr.shape[0] == 0):
        _fail(path, value, shape_doc)
    if arr.size == 0 and ndim:
        _fail(path, value, shape_doc)
    return arr


def _surface_points(path, value, key: Key):
    doc = "a grid of [x, y, z] control points (a list of rows of triples)"
    arr = _array(path, value, doc, key, ndim=3)
    if arr.shape[2] != 3 or min(arr.shape[:2]) < 2:
        _fail(path, value, doc + ", at least 2 x 2")
    return arr


def _text(path, value, key: Key):
    if not isinstance(value, str):
        _fail(path, value, "a string")
    limit = key.max_length or LIMITS["text"]
    if len(value) > limit:
        raise SceneError(path, f"has {len(value):,} characters; at most {limit} are allowed")
    bad = next((c for c in value if (ord(c) < 32 and c not in "\t\n") or 0xD800 <= ord(c) < 0xE000), None)
    if bad is not None:
        raise SceneError(path, f"holds the control character {bad!r}; expected printable text")
    if key.pattern and not re.fullmatch(key.pattern[0], value):
        _fail(path, value, key.pattern[1])
    return value


#: value kinds and what they accept (the ``type`` column of the reference)
KINDS = {
    "float": "a number",
    "int": "an integer",
    "bool": "true or false",
    "str": "a string",
    "str_list": "a list of strings",
    "vec3": "a list of 3 numbers",
    "points": "a list of [x, y, z] triples",
    "pairs": "a list of [i, j] node pairs",
    "positions": "a list of [i, j] grid positions (negative counts from the end)",
    "position": "one grid position [i, j] (negative counts from the end)",
    "index_list": "a node index or a list of them",
    "float_or_list": "a number or a list of numbers",
    "grid": "a grid of numbers (a list of rows)",
    "surface_points": "a grid of [x, y, z] points (a list of rows of triples)",
}


def check_value(path: str, value, key: Key):
    """Validate and convert one value."""
    k = key.kind
    if k == "float":
        return _number(path, value, key)
    if k == "int":
        return _number(path, value, key, integer=True)
    if k == "bool":
        if not isinstance(value, bool):
            _fail(path, value, "true or false")
        return value
    if k == "str":
        value = _text(path, value, key)
        if key.choices and value not in key.choices:
            _fail(path, value, "one of " + ", ".join(repr(c) for c in key.choices))
        return value
    if k == "str_list":
        if not isinstance(value, list):
            _fail(path, value, "a list of strings")
        if len(value) > LIMITS["list"]:
            raise SceneError(path, f"has {len(value):,} entries; at most {LIMITS['list']} are allowed")
        for i, v in enumerate(value):
            if not isinstance(v, str):
                _fail(f"{path}[{i}]", v, "a string (a list of strings)")
            _text(f"{path}[{i}]", v, key)
            if key.choices and v not in key.choices:
                _fail(f"{path}[{i}]", v, "entries from " + ", ".join(repr(c) for c in key.choices))
        return list(value)
    if k == "vec3":
        arr = _array(path, value, "a list of 3 numbers", key)
        if arr.shape != (3,):
            _fail(path, value, "a list of 3 numbers")
        return arr
    if k == "points":
        return _array(path, value, KINDS[k], key, ncol=3)
    if k == "pairs":
        return _array(path, value, KINDS[k], key, ncol=2, integer=True)
    if k == "positions":
        if isinstance(value, list) and len(value) == 2 and all(isinstance(v, int) and not isinstance(v, bool)
                                                                for v in value):
            value = [value]  # one position
        return _array(path, value, KINDS[k], key, ncol=2, integer=True)
    if k == "position":
        arr = _array(path, value, KINDS[k], key, integer=True)
        if arr.shape != (2,):
            _fail(path, value, KINDS[k])
        return arr
    if k == "index_list":
        if isinstance(value, int) and not isinstance(value, bool):
            value = [value]
        return _array(path, value, "a list of node indices", key, integer=True)
    if k == "float_or_list":
        if isinstance(value, list):
            return _array(path, value, KINDS[k], key)
        return _number(path, value, key)
    if k == "grid":
        return _array(path, value, KINDS[k], key, ndim=2)
    if k == "surface_points":
        return _surface_points(path, value, key)
    raise AssertionError(f"unknown key kind {k}")


def _join(path: str, name) -> str:
    return f"{path}.{name}" if path else str(name)


def _choice_text(values) -> str:
    return ", ".join(repr(v) for v in values)


def check_table(path: str, data, table: Table) -> dict:
    """Validate one table against its schema; fill defaults."""
    if not isinstance(data, dict):
        _fail(path, data, "a table")
    unknown = sorted((k for k in data if k not in table.keys), key=str)
    if unknown:
        allowed = ", ".join(sorted(table.keys))
        name = unknown[0] if isinstance(unknown[0], str) and len(unknown[0]) <= 40 else short(unknown[0], 40)
        raise SceneError(_join(path, name), f"unknown key; allowed keys here: {allowed}")
    selector = table.discriminator
    kind = None
    if selector is not None:
        spec = table.keys[selector]
        if selector in data:
            kind = check_value(_join(path, selector), data[selector], spec)
        elif spec.required:
            raise SceneError(_join(path, selector), "this key is required")
        else:
            kind = spec.default
    out = {}
    for name, spec in table.keys.items():
        sub = _join(path, name)
        if isinstance(spec, Table):
            if name not in data:
                if not spec.optional:
                    raise SceneError(sub, "this table is required")
                if spec.fill_defaults:
                    out[name] = check_table(sub, {}, spec)
                else:
                    out[name] = [] if spec.array else None
                continue
            if spec.array:
                value = data[name]
                if spec.accept_single and isinstance(value, dict):
                    out[name] = [check_table(sub, value, spec)]
                    continue
                if not isinstance(value, list):
                    _fail(sub, value, f"an array of tables ([[{sub}]])")
                out[name] = [check_table(f"{sub}[{i}]", item, spec) for i, item in enumerate(value)]
            else:
                out[name] = check_table(sub, data[name], spec)
            continue
        if spec.only and name in data and kind not in spec.only:
            raise SceneError(sub, f"does not apply to {selector} = {kind!r}; it applies to {selector} "
                             f"{_choice_text(spec.only)}")
        if name in data:
            out[name] = check_value(sub, data[name], spec)
        elif spec.required or (kind is not None and kind in spec.required_for):
            raise SceneError(sub, "this key is required" + (f" for {selector} = {kind!r}" if spec.required_for
                                                            else ""))
        else:
            out[name] = spec.default
    return out


def _default_text(key: Key) -> str:
    if key.required:
        return "required"
    text = "—" if key.default is None else f"`{key.default!r}`"  # None: not set (the meaning says what then)
    if key.required_for:
        need = f"required for {_choice_text(key.required_for)}"
        return need if key.default is None else f"{need}; else {text}"
    return text


def describe(table: Table, path: str = "", level: int = 2) -> list[str]:
    """Markdown reference of a schema table."""
    lines = []
    scalars = {k: v for k, v in table.keys.items() if isinstance(v, Key)}
    if scalars:
        lines += ["| key | type | unit | default | meaning |", "|---|---|---|---|---|"]
        for name, key in scalars.items():
            doc = key.doc
            if key.choices:
                doc += f" One of: {_choice_text(key.choices)}."
            if key.minimum is not None and key.minimum != 0:
                doc += f" {'Greater than' if key.exclusive_minimum else 'At least'} {key.minimum}."
            if key.maximum is not None:
                doc += f" At most {key.maximum}."
            if key.magnitude is not None:
                doc += f" Magnitude at most {_bound_text(key.magnitude, key.unit)}."
            if key.max_length is not None:
                doc += f" At most {key.max_length} characters."
            if key.only:
                doc += f" Only for {table.discriminator} {_choice_text(key.only)}."
            lines.append(f"| `{name}` | {key.kind} | {key.unit} | {_default_text(key)} | {doc} |")
        lines.append("")
    for name, sub in table.keys.items():
        if isinstance(sub, Table):
            head = f"[[{path}{name}]]" if sub.array else f"[{path}{name}]"
            lines += [f"{'#' * level} `{head}`", "", sub.doc, ""]
            lines += describe(sub, f"{path}{name}.", level + 1)
    return lines


def limits_text(level: int = 3) -> list[str]:
    """Markdown of the limits every value is checked against (:data:`LIMITS`, :data:`UNIT_BOUNDS`)."""
    units = {}
    for unit, bound in UNIT_BOUNDS.items():
        units.setdefault(bound, []).append(f"`{unit}`")
    return [
        f"{'#' * level} Limits", "",
        "Beyond these a value is a typing error or a unit off: the scene is refused with the key, the value and "
        "the limit, before anything is built.", "",
        "| what | at most |", "|---|---|",
        "| magnitude of a number, by unit | " + "; ".join(f"{_bound_text(b, '')} ({', '.join(u)})"
                                                     for b, u in units.items()) + " |",
        f"| magnitude of a dimensionless number | {_bound_text(LIMITS['number'], '')} |",
        f"| magnitude of an integer (counts, node numbers, grid positions) | {_bound_text(LIMITS['integer'], '')} |",
        f"| characters of a string (unless its key says otherwise) | {LIMITS['text']} |",
        f"| entries of a list of strings | {LIMITS['list']} |",
        f"| entries along one dimension of an array; nodes of a structure | {LIMITS['items']:,} |",
        "",
        "Entries of a number array must be numbers (`true` and `\"0.5\"` are not); strings hold no control "
        "characters other than tab and newline. A scene file is UTF-8 text of at most "
        f"{LIMITS['scene_bytes'] // 2**20} MiB; a mesh file "
        "(`geometry.file`, relative to the scene file) is a regular file of at most 2 GiB whose extension names a "
        "format meshio reads.", "",
    ]


def reference(table: Table, level: int = 3) -> str:
    """The Markdown reference of a scene schema: every table and key, the value types, then the limits."""
    kinds = ["| type | a value is |", "|---|---|"] + [f"| {k} | {v} |" for k, v in KINDS.items()]
    return "\n".join(describe(table, level=level) + [f"{'#' * level} Value types", ""] + kinds + [""]
                     + limits_text(level))


# -- the scene schema ---------------------------------------------------------------------------

EFFECTS = ("axial", "rope", "loads", "gravity", "imperfection")
PLANFORMS = ("rectangle", "ellipse", "disk", "bspline")
GEOMETRIES = PLANFORMS + ("hemisphere", "file")
ANALYSES = ("static", "continuation", "dynamics", "mra", "form_and_buckle", "indentation")
#: analyses that suit each source of geometry (the first is the default)
ANALYSES_OF = {
    "nodes": ("static", "continuation", "dynamics"),
    "file": ("static", "continuation", "dynamics"),
    "planform": ("mra", "form_and_buckle"),
    "hemisphere": ("indentation",),
}
#: named node sets of a planform grid (:class:`~shellform.geometry.grids.QuadGrid`)
GRID_GROUPS = ("boundary", "corners", "south", "east", "north", "west", "sw", "se", "ne", "nw")
BAR_ROPE = ANALYSES_OF["nodes"]
FORM_FINDING = ANALYSES_OF["planform"]

_POS = dict(minimum=0.0, exclusive_minimum=True)
#: divisions of a grid per side: far beyond any net that fits in memory is a typing error
_DIVISIONS = dict(minimum=1, maximum=10_000)
_NONNEG = dict(minimum=0.0)
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
        "file": Key("str", "Mesh file read by meshio (.vtu, .msh, .obj, ...), relative to the scene file. Line "
                    "cells become members, and so do the edges of triangle and quad cells (each once).",
                    default=None, only=("file",), required_for=("file",), max_length=1000),
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
        "z": Key("float", "Every node at this height (within z_tolerance).", default=None, unit="m"),
        "z_tolerance": Key("float", "Tolerance of z.", default=1.0e-6, unit="m", **_NONNEG),
        "dofs": Key("str", "Fixed components, any of the letters x, y, z.", default="xyz"),
    },
)

# the relaxation's defaults are the solver's own, written once in its options
_RELAX, _REFINE = RelaxationOptions(), Refinements()

RELAXATION = Table(
    fill_defaults=True,
    doc="MRA form finding by dynamic relaxation (analysis 'mra' and 'form_and_buckle'). Also read from a "
        "top-level [solver] table.",
    keys={
        "scheme": Key("str", "Relaxation scheme: pseudo-transient Newton (fast), the paper's explicit RK4, or "
                      "leapfrog with kinetic damping.", default=_RELAX.scheme, choices=("implicit", "rk4", "kinetic")),
        "rtol": Key("float", "Rest: every nodal acceleration <= rtol g and velocity <= rtol sqrt(g L).",
                    default=_RELAX.rtol, **_POS),
        "velocity_tol": Key("float", "Explicit velocity tolerance (default from rtol).", default=_RELAX.velocity_tol, unit="m/s",
                            **_POS),
        "acceleration_tol": Key("float", "Explicit acceleration tolerance (default from rtol).", default=_RELAX.acceleration_tol,
                                unit="m/s^2", **_POS),
        "max_iterations": Key("int", "Give up after this many steps (default 500 implicit, 2,000,000 explicit).",
                              default=_RELAX.max_iterations, minimum=1),
        "max_wall_time": Key("float", "Give up after this many seconds (default: no limit).", default=_RELAX.max_wall_time, unit="s", **_POS),
        "damping": Key("float", "Viscous damping per unit mass (default 2 sqrt(g / L)).", default=_RELAX.damping, unit="1/s",
                       **_NONNEG),
        "linear_solver": Key("str", "Linear solver of the implicit scheme: 'auto' is 'cholesky' (supernodal "
                             "CHOLMOD); 'ldl' (QDLDL), 'nd' (SuperLU in nested-dissection order), 'amg' (soft nets "
                             "only) or 'direct'.", default=_RELAX.linear_solver,
                             choices=("auto", "cholesky", "ldl", "nd", "amg", "direct")),
        "slack_active_set": Key("bool", "Implicit scheme: solve each step again with the slack ropes it would "
                                "stretch modelled as taut: about half the steps, each up to three solves.", default=_REFINE.slack_active_set),
        "front_sweeps": Key("bool", "Implicit scheme: after a step that leaves only a few nodes out of balance "
                            "(along the fronts between taut and slack regions), take up to three Newton steps on the "
                            "nodes within four ropes of them, the rest of the net held.", default=_REFINE.front_sweeps),
        "factor_correction": Key("bool", "Implicit scheme: before refactorising the tangent, try conjugate gradients "
                                 "with the kept factorisation corrected by an exact solve on the nodes whose tangent "
                                 "entries changed (ropes pulled taut or gone slack).", default=_REFINE.factor_correction),
        "slack_settling": Key("bool", "Implicit scheme: when a step gets ropes' slack state wrong (slack ropes it "
                              "stretches outside its active set, taut ones it shortens below their rest length), "
                              "settle them by Newton steps on the step's model over the nodes within three ropes of "
                              "them (needs slack_active_set).", default=_REFINE.slack_settling),
        "step_repair": Key("bool", "Implicit scheme: when a few ropes make a step of the whole net overshoot, keep "
                           "the full step and relax the nodes within three ropes of them from there instead of "
                           "shortening the whole step (needs slack_active_set).", default=_REFINE.step_repair),
        "start": Key("str", "Start of a relaxation without a [start] surface: 'auto' is, for the implicit "
                     f"scheme, the coarse net's start on nets of {COARSE_START_NODES:,} nodes or more and the force-density shape "
                     "below, and the flat planform for the explicit ones (as in the paper); 'reference' forces the "
                     "planform, 'force_density' the force-density shape, 'coarse_net' the shape of the net with "
                     "every third grid line, hung first, interpolated and hung a little deeper.", default="auto",
                     choices=("auto", "reference", "force_density", "coarse_net")),
        "dt": Key("float", "Explicit time step (default 90 % of the stability bound) or first pseudo time step.",
                  default=_RELAX.dt, unit="s", **_POS),
        "checkpoint_interval": Key("float", "Save the relaxation state to DIR/relaxation_checkpoint.npz at most "
                                   "this often (and when it stops unconverged); `--resume` restarts from it.",
                                   default=5.0, unit="s", **_NONNEG),
    },
)

START_SHAPE = Table(
    fill_defaults=True,
    doc="Start shape of the form finding. Also read from a top-level [start] table.",
    keys={
        "type": Key("str", "No start surface ('flat': the [solver] start decides, the planform for the explicit "
                    "schemes), a B-spline dish, a B-spline fitted to a coarser hanging net, or the shape in balance "
                    "with the force densities of a coarser hanging net.",
                    default="flat", choices=("flat", "nurbs", "coarse_nurbs", "coarse_force_density")),
        "depth": Key("float", "nurbs: depth of the dish.", default=None, unit="m"),
        "control_heights": Key("grid", "nurbs: control heights over the planform box (instead of depth).",
                               default=None, unit="m"),
        "coarsening": Key("int", "coarse_nurbs, coarse_force_density: the coarse net has this many times fewer "
                          "quads per side.",
                          default=4, minimum=1),
        "n_ctrl": Key("int", "coarse_nurbs: control points per direction of the fitted surface.", default=6,
                      minimum=2),
        "compare_flat": Key("bool", "Also relax from the flat start and report the iterations and time saved.",
                            default=False),
    },
)

LENGTHS = Table(
    fill_defaults=True,
    doc="Rope length statistics and control (analysis 'mra'). Also read from a top-level [lengths] table.",
    keys={
        "tolerance": Key("float", "Relative tolerance for 'the same length'.", default=0.01, **_POS),
        "target": Key("float", "Count the ropes within tolerance of this length (default: no count).", default=None, unit="m", **_POS),
        "control": Key("bool", "Drive the ropes towards n_classes lengths.", default=False),
        "n_classes": Key("int", "Length classes of the control.", default=3, minimum=1),
        "rounds": Key("int", "Rounds of the control.", default=4, minimum=1),
    },
)

BUCKLING = Table(
    fill_defaults=True,
    doc="Buckling of the rod gridshell built on the found form (analysis 'form_and_buckle'): the inverted net's "
        "grid lines become rods ([rods]), pinned at the suspension points, loaded by the net's weight times a "
        "load factor traced by arc-length continuation to the first critical point. Also read from a top-level "
        "[buckling] table (which may hold the [rods] keys E, G, radius, density and rest_shape too).",
    keys={
        "load_factor_max": Key("float", "Stop when the load factor exceeds this.", default=100.0, **_POS),
        "max_steps": Key("int", "Continuation steps before stopping.", default=60, minimum=1),
        "initial_increment": Key("float", "First load-factor increment (default 1/20 of load_factor_max).",
                                 default=None, **_POS),
        "checkpoint_every": Key("int", "Checkpoint of the path every this many steps.", default=10, minimum=1),
    },
)

INDENTATION = Table(
    fill_defaults=True,
    doc="Apex indentation of the hemisphere (analysis 'indentation'): pre-stress on the net, push the apex down "
        "by dD in displacement control through every snap (gridshell paper). The imperfection is random dead "
        "forces ([imperfection] type 'forces'; default 1e-4 EI/R^2, seed 0).",
    keys={
        "mode": Key("str", "I: apex node(s) prescribed, rods rotate freely; II: apex and its neighbours on the "
                    "central rods move together (clamped-like).", default="I", choices=("I", "II")),
        "max_displacement": Key("float", "Final apex displacement dD / R.", default=2.0, **_POS),
        "increment": Key("float", "First continuation step, as dD / R.", default=0.01, **_POS),
        "snap_method": Key("str", "How the stable state after a snap is found: damped implicit Euler dynamics, "
                           "energy descent, or descent first.", default="dynamic",
                           choices=("dynamic", "energy", "auto")),
        "max_snaps": Key("int", "Stop after this many losses of stability.", default=12, minimum=1),
        "max_steps": Key("int", "Continuation steps before stopping.", default=3000, minimum=1),
    },
)

DYNAMICS = Table(
    fill_defaults=True,
    doc="Time stepping by implicit Euler (analysis 'dynamics'; gridshell paper, Eq. 2): lumped masses from "
        "mass_per_length and [masses], damping C = c M, the loads times the load factor (ramped over ramp_time).",
    keys={
        "time_step": Key("float", "Time step h (halved where Newton fails, grown back after). Required for "
                         "analysis 'dynamics'.", default=None,
                         unit="s", **_POS),
        "duration": Key("float", "Simulated time. Required for analysis 'dynamics'.", default=None, unit="s", **_POS),
        "damping": Key("float", "Mass-proportional damping coefficient c.", default=0.0, unit="1/s", **_NONNEG),
        "ramp_time": Key("float", "The load factor rises linearly from 0 over this time (0: applied at once).",
                         default=0.0, unit="s", **_NONNEG),
        "output_every": Key("int", "Write every k-th step to the XDMF time series.", default=1, minimum=1),
        "monitor_node": Key("int", "Node whose displacement is tabulated and plotted (default: none; the "
                            "largest node displacement is tabulated and plotted in any case).", default=None,
                            minimum=0),
        "monitor_component": Key("str", "Component of monitor_node.", default="z", choices=("x", "y", "z")),
        "checkpoint_interval": Key("float", "Save the state to DIR/dynamics_checkpoint.npz at most this often; "
                                   "`--resume` continues from it.", default=5.0, unit="s", **_NONNEG),
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
        "rods": Table(
            doc="Solid circular discrete elastic rods: the hemisphere's (defaults: the paper's 1 mm radius, "
                "E = 100 GPa, G = E/3, 1000 kg/m^3) and those of the gridshell built on a found form "
                "(defaults: 20 mm radius, E = 210 GPa, G = E/2.6, weightless: the net's weight is the load).",
            keys={
                "E": Key("float", "Young's modulus (default above).", default=None, unit="Pa", **_POS),
                "G": Key("float", "Shear modulus (default above).", default=None, unit="Pa", **_POS),
                "radius": Key("float", "Radius of the section (default above).", default=None, unit="m", **_POS),
                "density": Key("float", "Density of the rods (default above).", default=None, unit="kg/m^3", **_NONNEG),
                "rest_shape": Key("str", "form_and_buckle: rods straight when unstressed (bent into the form, the "
                                  "prestress relaxed first) or stress-free in the found shape.", default="straight",
                                  choices=("straight", "found")),
                "joints": Key("str", "hemisphere: rods tied at a joint by a penalty spring between two nodes (the "
                              "paper's Eq. 3), or sharing one node.", default="penalty",
                              choices=("penalty", "shared")),
                "joint_stiffness_ratio": Key("float", "hemisphere: penalty stiffness over the rods' axial "
                                             "stiffness at the joint.", default=1.0e3, **_POS),
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
                               "needs the rhino extra). Paths and time series are XDMF whatever this says. Form "
                               "finding writes its VTU meshes (see meshes) and, with '3dm', form.3dm.",
                               default=["vtu", "xdmf"], choices=("vtu", "vtk", "xdmf", "3dm")),
                "meshes": Key("bool", "Form finding: write the hanging net, the inverted net and the inverted "
                              "shell surface (hanging.vtu, inverted.vtu, inverted_shell.vtu).", default=True),
            },
        ),
    },
)
