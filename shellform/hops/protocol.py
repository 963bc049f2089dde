"""The Hops protocol: typed parameters, and values to and from Hops data trees.

Grasshopper's Hops component asks a server for the components it serves
(``GET /``), for one component's inputs and outputs (``GET /<name>``), and
solves by ``POST /solve`` with a JSON schema: ``pointer`` (the component's
name), ``values`` (one data tree per input: ``{"ParamName": name,
"InnerTree": {"{0}": [{"type": ..., "data": ...}, ...]}}``). The reply is
the same schema with the outputs' data trees in ``values`` and the messages
Grasshopper shows on the component in ``errors`` and ``warnings``.

Each item's ``data`` is JSON text: a number (``"1.5"``), a string
(``"\\"boundary\\""``), a point (``{"X": .., "Y": .., "Z": ..}``), a line
(``{"From": point, "To": point}``) or, for curves and meshes, the rhino3dm
encoding of the object (``CommonObject.Encode``).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Any

import numpy as np

#: Hops parameter type -> the type name of its items
RESULT_TYPES = {
    "Number": "System.Double", "Integer": "System.Int32", "Boolean": "System.Boolean", "Text": "System.String",
    "Point": "Rhino.Geometry.Point3d", "Vector": "Rhino.Geometry.Vector3d", "Line": "Rhino.Geometry.Line",
    "Curve": "Rhino.Geometry.Curve", "Mesh": "Rhino.Geometry.Mesh",
}
_MAX_ITEMS = 2147483647


class InputError(ValueError):
    """An input that cannot be decoded or used; the message names the input."""

    def __init__(self, name: str, problem: str):
        self.name = name
        super().__init__(f"{name}: {problem}")


@dataclass(frozen=True)
class Param:
    """One input or output of a component.

    ``key`` is the scene key the input fills (its checks and messages are the
    scene's); ``many`` makes it a list; an input with a ``default`` or
    ``optional`` may be left unconnected.
    """

    name: str
    kind: str
    doc: str
    unit: str = ""
    many: bool = False
    default: Any = None
    optional: bool = False
    key: str = ""

    @property
    def required(self) -> bool:
        return self.default is None and not self.optional

    def describe(self, output: bool = False) -> dict:
        unit = f" [{self.unit}]" if self.unit else ""
        text = f"{self.doc}{unit}" + (f" (scene key {self.key})" if self.key else "")
        out = {"Name": self.name, "Nickname": self.name, "Description": text, "ParamType": self.kind,
               "ResultType": RESULT_TYPES[self.kind]}
        if output:
            return out
        out["AtLeast"] = 1 if self.required else 0
        out["AtMost"] = _MAX_ITEMS if self.many else 1
        if self.default is not None:
            out["Default"] = self.default
        return out


def _point(d) -> list[float]:
    return [float(d["X"]), float(d["Y"]), float(d["Z"])]


def decode_item(param: Param, item) -> Any:
    """One item of an input's data tree as a Python value (numbers, strings, lists of 3, rhino3dm objects)."""
    if not isinstance(item, dict) or "data" not in item:
        raise InputError(param.name, "an item of its data tree is not {type, data}")
    raw = item["data"]
    try:
        data = json.loads(raw) if isinstance(raw, str) else raw
    except ValueError:
        data = raw  # a bare string
    kind = str(item.get("type", ""))
    try:
        if kind in ("Rhino.Geometry.Point3d", "Rhino.Geometry.Vector3d", "Rhino.Geometry.Point3f"):
            return _point(data)
        if kind == "Rhino.Geometry.Line":
            return [_point(data["From"]), _point(data["To"])]
        if kind.startswith("Rhino.Geometry."):
            import rhino3dm

            obj = rhino3dm.CommonObject.Decode(data)
            if obj is None:
                raise ValueError("not a rhino3dm object")
            return obj
    except (KeyError, TypeError, ValueError) as exc:
        raise InputError(param.name, f"cannot decode its {kind} item ({exc})") from None
    if kind == "System.Int32" and isinstance(data, float) and data.is_integer():
        return int(data)
    return data


def decode_tree(param: Param, tree: dict) -> Any:
    """The value of an input: one item, a list (``many``), or None when it holds nothing."""
    inner = tree.get("InnerTree") or {}
    if not isinstance(inner, dict):
        raise InputError(param.name, "its InnerTree is not a table of branches")
    items = [decode_item(param, it) for key in sorted(inner) for it in (inner[key] or [])]
    if param.many:
        return items or None
    if len(items) > 1:
        raise InputError(param.name, f"takes one item, got {len(items)}")
    return items[0] if items else None


def _encode(kind: str, value) -> str:
    if kind == "Number":
        return json.dumps(float(value))
    if kind == "Integer":
        return str(int(value))
    if kind == "Boolean":
        return "true" if bool(value) else "false"
    if kind == "Text":
        return json.dumps(str(value))
    if kind in ("Point", "Vector"):
        x, y, z = (float(v) for v in value)
        return json.dumps({"X": x, "Y": y, "Z": z})
    if kind == "Line":
        a, b = np.asarray(value, dtype=float)
        return json.dumps({"From": {"X": a[0], "Y": a[1], "Z": a[2]}, "To": {"X": b[0], "Y": b[1], "Z": b[2]}})
    return json.dumps(value.Encode())  # a rhino3dm object


#: the JSON text of an item of the kinds with a fixed layout of numbers, as ``_encode`` writes it
#: (``json.dumps`` writes a finite float as its ``repr``), and how many numbers it holds
_POINT = '{{"X": {!r}, "Y": {!r}, "Z": {!r}}}'
_LAYOUTS = {"Number": ("{!r}", 1), "Point": (_POINT, 3), "Vector": (_POINT, 3),
            "Line": ('{{"From": ' + _POINT + ', "To": ' + _POINT + '}}', 6)}


def _encode_many(kind: str, items) -> list[str]:
    """The ``data`` of every item of a list: what ``_encode`` gives one by one, formatted from one array.

    An output of a thousand lines took 26 ms item by item (a dictionary and a
    ``json.dumps`` each) and takes 4 ms here. Items that are not all finite
    numbers of the kind's layout are encoded one by one.
    """
    layout = _LAYOUTS.get(kind)
    if layout is not None and len(items):
        template, width = layout
        try:
            numbers = np.asarray(items, dtype=float).reshape(len(items), -1)
        except (TypeError, ValueError):
            numbers = None
        if numbers is not None and numbers.shape[1] == width and np.isfinite(numbers).all():
            return [template.format(*row) for row in numbers.tolist()]
    return [_encode(kind, v) for v in items]


def encode_tree(param: Param, value) -> dict:
    """The data tree of an output: a value, a list (``many``) or a dict branch -> list (``{k}`` paths)."""
    kind, rtype = param.kind, RESULT_TYPES[param.kind]
    if isinstance(value, dict):
        branches = value
    elif param.many:
        branches = {0: value if isinstance(value, np.ndarray) else list(value)}
    else:
        branches = {0: [] if value is None else [value]}
    inner = {f"{{{k}}}": [{"type": rtype, "data": data} for data in _encode_many(kind, items)]
             for k, items in branches.items()}
    return {"ParamName": param.name, "InnerTree": inner}


def encode_input(param: Param, value) -> dict:
    """The data tree Hops sends for an input (for clients and tests): items typed as Grasshopper types them."""
    items = value if param.many else [value]
    out = []
    for v in items:
        if param.kind in ("Curve", "Mesh"):
            out.append({"type": f"Rhino.Geometry.{type(v).__name__}", "data": json.dumps(v.Encode())})
        else:
            out.append({"type": RESULT_TYPES[param.kind], "data": _encode(param.kind, v)})
    return {"ParamName": param.name, "InnerTree": {"{0}": out}}
