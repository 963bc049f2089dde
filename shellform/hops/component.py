"""What every Hops component is: its inputs and outputs, the scene it builds, its reply; shared helpers."""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .protocol import InputError

#: points closer than this times the size of the model are one node (mesh vertices, ends of lines)
JOIN_TOLERANCE = 1.0e-6


@dataclass
class Built:
    """A scene built from a component's inputs, and what its reply needs besides the run's files."""

    scene: dict
    #: scene key prefix -> input name, to name the input in a scene error
    inputs: dict = field(default_factory=dict)
    context: dict = field(default_factory=dict)
    #: files the scene reads (file name -> a function writing it to a path): the server writes them into
    #: the request's own folder and reads the scene from there, so no input ever names a path
    files: dict[str, Callable[[Path], None]] = field(default_factory=dict)


@dataclass(frozen=True)
class Component:
    name: str
    description: str
    inputs: tuple
    outputs: tuple
    build: object  # (values) -> Built
    reply: object  # (Result, values, context) -> {output name: value}

    def describe(self) -> dict:
        return {"Uri": f"/{self.name}", "Name": self.name, "Nickname": self.name, "Description": self.description,
                "Category": "shellform", "Subcategory": "analysis",
                "Inputs": [p.describe() for p in self.inputs], "Outputs": [p.describe(True) for p in self.outputs],
                "InputNames": [p.name for p in self.inputs], "OutputNames": [p.name for p in self.outputs]}


def one_source(values: dict, names: tuple[str, ...], what: str) -> str:
    """The one input of ``names`` that is given (the sources of a component's geometry, ``what`` says each)."""
    given = [n for n in names if values.get(n) is not None]
    choices = " or ".join(names) if len(names) < 3 else f"{', '.join(names[:-1])} or {names[-1]}"
    if not given:
        raise InputError(choices, f"one is required: {what}")
    if len(given) > 1:
        raise InputError(given[1], f"give only one of {choices}; got {given[0]} and {given[1]}")
    return given[0]


def nearest_nodes(nodes: np.ndarray, points, tol: float, name: str) -> list[int]:
    """The node at each point (within ``tol``)."""
    from scipy.spatial import cKDTree

    pts = np.asarray(points, dtype=float).reshape(-1, 3)
    dist, idx = cKDTree(nodes).query(pts)
    far = np.flatnonzero(dist > tol)
    if far.size:
        k = int(far[0])
        x = pts[k]
        raise InputError(name, f"item {k} at ({x[0]:.6g}, {x[1]:.6g}, {x[2]:.6g}) m is no node of the structure "
                         f"(the nearest is {dist[k]:.3g} m away; tolerance {tol:.3g} m)")
    return [int(i) for i in idx]


def line_pairs(points, cells) -> np.ndarray:
    """The end points of every line cell, shape (m, 2, 3)."""
    return np.asarray(points, dtype=float)[np.asarray(cells, dtype=np.int64).reshape(-1, 2)]


def report(summary: dict, keys) -> str:
    return json.dumps({k: summary[k] for k in keys if k in summary}, indent=1, default=str)


def cell_field(mesh, name, family="line"):
    k = [i for i, c in enumerate(mesh.cells) if c.type == family][0]
    return mesh.cell_data[name][k] if name in mesh.cell_data else None
