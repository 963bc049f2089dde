"""A state as a COMPAS graph (``compas.datastructures.Graph`` JSON), for compas and its plugins.

Nodes carry ``x, y, z`` (the current position), ``displacement`` and
``reaction``; every member or joint is an edge with the results its effects
compute (the fields of :func:`~shellform.io.mesh.state_mesh`; a result a cell
does not have is left out of that edge's attributes, not written as 0). The
file is plain JSON in the format ``compas.data.json_load`` reads, so writing it
needs no compas installation.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from .files import write_text
from .mesh import state_mesh


def compas_graph_data(system, q: np.ndarray, lam: float = 1.0) -> dict:
    """The JSON-ready ``compas.datastructures/Graph`` of state ``q``."""
    mesh = state_mesh(system, q, lam)
    x = mesh.points
    displacement, reaction = mesh.point_data["displacement"], mesh.point_data["reaction"]
    nodes = {str(i): {"x": float(p[0]), "y": float(p[1]), "z": float(p[2]),
                      "displacement": displacement[i].tolist(), "reaction": reaction[i].tolist()}
             for i, p in enumerate(x)}
    edges: dict[str, dict] = {str(i): {} for i in range(len(x))}
    fields = {name: blocks[0] for name, blocks in mesh.cell_data.items()}
    for k, (a, b) in enumerate(mesh.cells[0].data):
        attributes = {}
        for name, values in fields.items():
            v = values[k]
            if np.isfinite(v):
                attributes[name] = int(v) if name in ("group", "slack") else float(v)
        edges[str(a)][str(b)] = attributes
    return {
        "dtype": "compas.datastructures/Graph",
        "data": {"attributes": {"name": "shellform state", "load_factor": float(lam)},
                 "default_node_attributes": {"x": 0.0, "y": 0.0, "z": 0.0},
                 "default_edge_attributes": {}, "node": nodes, "edge": edges, "max_node": len(x) - 1},
    }


def write_compas_graph(path, system, q: np.ndarray, lam: float = 1.0) -> Path:
    """Write state ``q`` as a COMPAS graph JSON file."""
    return write_text(path, json.dumps(compas_graph_data(system, q, lam)))
