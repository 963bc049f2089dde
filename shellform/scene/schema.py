"""Scene schema: every key, its type, unit, default and meaning.

:class:`Key` and :class:`Table` describe a TOML table; :func:`check_table`
validates data against one (errors name the key, the value and what is
allowed) and :func:`reference` writes the Markdown reference. The scene format
itself, :data:`~shellform.scene.format.SCENE`, is in :mod:`shellform.scene.format`.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import SceneError

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
#: bounds shared by many keys: ``Key(..., **POSITIVE)``
POSITIVE = dict(minimum=0.0, exclusive_minimum=True)
NONNEGATIVE = dict(minimum=0.0)

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
