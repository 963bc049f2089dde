"""Meshes of a form-found net: the hanging net and its inverted shell (VTU).

Ropes are line cells, the grid's faces quad and triangle cells; the rope
results are cell data of the lines.
"""

from __future__ import annotations

from pathlib import Path

import meshio
import numpy as np

from .mesh import write_mesh


def net_mesh(net, positions, member_fields: dict, point_fields: dict | None = None) -> meshio.Mesh:
    """Ropes (lines) and grid faces (quads, triangles) of a :class:`~shellform.mra.net.HangingNet` at ``positions``.

    The faces carry no rope results: their cells of a rope field are NaN (not
    computed), never a zero that colours every face as an unloaded, taut rope.
    """
    faces = list(net.grid.faces.items())
    cells = [("line", net.rope_edges)] + faces
    cell_data = {k: [np.asarray(v, dtype=float)] + [np.full(len(f), np.nan) for _, f in faces]
                 for k, v in member_fields.items()}
    support = np.zeros(net.structure.n_nodes)
    support[net.supports] = 1.0
    point_data = {"support": support, **(point_fields or {})}
    return meshio.Mesh(points=np.asarray(positions, dtype=float), cells=cells, point_data=point_data,
                       cell_data=cell_data)


def _reactions(net, res) -> np.ndarray:
    """Support reactions at every node [N] (0 at free nodes, as in a state's ``reaction``)."""
    R = np.zeros((net.structure.n_nodes, 3))
    R[net.supports] = res.reactions
    return R


def write_net_meshes(out: Path, res, inv, tag: str = "") -> list[str]:
    """``hanging{tag}.vtu`` of a form-finding result and ``inverted{tag}.vtu`` of its inverted shell.

    ``inv`` (an :class:`~shellform.mra.inversion.InvertedShell`) may be None:
    the inversion failed, and only the hanging net is written. Returns the
    names of the files written.
    """
    net = res.net
    hang = net_mesh(net, res.positions,
                    {"tension": res.tension, "slack": res.slack.astype(float), "length": res.length,
                     "rest_length": net.rest_length, "strain": res.strain, "family": net.family.astype(float)},
                    {"displacement": res.positions - net.structure.nodes, "reaction": _reactions(net, res)})
    names = [f"hanging{tag}.vtu"]
    write_mesh(out / names[0], hang)
    if inv is not None:
        dome = net_mesh(net, inv.positions, {"axial_force": inv.force, "length": res.length,
                                             "family": net.family.astype(float)})
        names.append(f"inverted{tag}.vtu")
        write_mesh(out / names[1], dome)
    return names
