"""Scene schema: every key, its type, unit, default and meaning.

The same table validates scenes (errors name the key, the value and what is
allowed), prints with ``shellform schema`` and generates the reference in
``docs/scenes.md``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .errors import SceneError

_REQUIRED = object()


@dataclass(frozen=True)
class Key:
    """One scalar or array entry of a scene table."""

    kind: str  # float, int, str, bool, vec3, points, pairs, index_list, float_or_list, str_list
    doc: str
    default: Any = _REQUIRED
    unit: str = ""
    choices: tuple = ()
    minimum: float | None = None
    exclusive_minimum: bool = False

    @property
    def required(self) -> bool:
        return self.default is _REQUIRED


@dataclass(frozen=True)
class Table:
    """A TOML table (``[name]``) or, with ``array=True``, an array of tables (``[[name]]``)."""

    keys: dict
    doc: str
    array: bool = False
    optional: bool = True
    #: when absent, behave as if present with every default (else None)
    fill_defaults: bool = False


def _fail(path, value, allowed):
    shown = repr(value)
    if len(shown) > 60:
        shown = shown[:57] + "..."
    raise SceneError(path, f"got {shown}; expected {allowed}")


def _number(path, value, key: Key, integer=False):
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        _fail(path, value, "an integer" if integer else "a number")
    if integer and not isinstance(value, int):
        _fail(path, value, "an integer")
    if not np.isfinite(value):
        _fail(path, value, "a finite number")
    if key.minimum is not None:
        if value < key.minimum or (key.exclusive_minimum and value == key.minimum):
            rel = ">" if key.exclusive_minimum else ">="
            _fail(path, value, f"a number {rel} {key.minimum}")
    return int(value) if integer else float(value)


def _array(path, value, shape_doc, ncol=None, integer=False):
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        _fail(path, value, shape_doc)
    if arr.dtype == object:
        _fail(path, value, shape_doc)
    if ncol is not None and (arr.ndim != 2 or arr.shape[1] != ncol or arr.shape[0] == 0):
        _fail(path, value, shape_doc)
    if ncol is None and arr.ndim != 1:
        _fail(path, value, shape_doc)
    bad = np.argwhere(~np.isfinite(arr))
    if bad.size:
        raise SceneError(f"{path}{[int(i) for i in bad[0]]}", "value is not finite")
    if integer:
        if np.any(arr != np.round(arr)):
            _fail(path, value, shape_doc + " of integers")
        return arr.astype(np.int64)
    return arr


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
        if not isinstance(value, str):
            _fail(path, value, "a string")
        if key.choices and value not in key.choices:
            _fail(path, value, "one of " + ", ".join(repr(c) for c in key.choices))
        return value
    if k == "str_list":
        if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
            _fail(path, value, "a list of strings")
        for v in value:
            if key.choices and v not in key.choices:
                _fail(path, v, "entries from " + ", ".join(repr(c) for c in key.choices))
        return list(value)
    if k == "vec3":
        arr = _array(path, value, "a list of 3 numbers")
        if arr.shape != (3,):
            _fail(path, value, "a list of 3 numbers")
        return arr
    if k == "points":
        return _array(path, value, "a list of [x, y, z] triples", ncol=3)
    if k == "pairs":
        return _array(path, value, "a list of [i, j] node pairs", ncol=2, integer=True)
    if k == "index_list":
        if isinstance(value, int) and not isinstance(value, bool):
            value = [value]
        return _array(path, value, "a list of node indices", integer=True)
    if k == "float_or_list":
        if isinstance(value, list):
            return _array(path, value, "a number or a list of numbers")
        return _number(path, value, key)
    raise AssertionError(f"unknown key kind {k}")


def check_table(path: str, data, table: Table) -> dict:
    """Validate one table against its schema; fill defaults."""
    if not isinstance(data, dict):
        _fail(path, data, "a table")
    unknown = sorted(set(data) - set(table.keys))
    if unknown:
        allowed = ", ".join(sorted(table.keys))
        raise SceneError(f"{path}.{unknown[0]}" if path else unknown[0], f"unknown key; allowed keys here: {allowed}")
    out = {}
    for name, spec in table.keys.items():
        sub = f"{path}.{name}" if path else name
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
                if not isinstance(data[name], list):
                    _fail(sub, data[name], f"an array of tables ([[{sub}]])")
                out[name] = [check_table(f"{sub}[{i}]", item, spec) for i, item in enumerate(data[name])]
            else:
                out[name] = check_table(sub, data[name], spec)
        elif name in data:
            out[name] = check_value(sub, data[name], spec)
        elif spec.required:
            raise SceneError(sub, "this key is required")
        else:
            out[name] = spec.default
    return out


def describe(table: Table, path: str = "", level: int = 2) -> list[str]:
    """Markdown reference of a schema table."""
    lines = []
    scalars = {k: v for k, v in table.keys.items() if isinstance(v, Key)}
    if scalars:
        lines += ["| key | type | unit | default | meaning |", "|---|---|---|---|---|"]
        for name, key in scalars.items():
            default = "required" if key.required else f"`{key.default!r}`"
            doc = key.doc + (f" One of: {', '.join(repr(c) for c in key.choices)}." if key.choices else "")
            lines.append(f"| `{name}` | {key.kind} | {key.unit} | {default} | {doc} |")
        lines.append("")
    for name, sub in table.keys.items():
        if isinstance(sub, Table):
            head = f"[[{path}{name}]]" if sub.array else f"[{path}{name}]"
            lines += [f"{'#' * level} `{head}`", "", sub.doc, ""]
            lines += describe(sub, f"{path}{name}.", level + 1)
    return lines
