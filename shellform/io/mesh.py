"""meshio export of states and state sequences (ParaView reads both).

Members are written as line cells in one block, nodes as points at their
current position. Point data: ``displacement`` and ``reaction``. Cell data:
``group`` (the member group number, in the order the groups were added) and
the member results that the members' effects compute: ``axial_force``,
``strain``, ``slack`` (1 for a slack rope, 0 for a taut one). A result that no
group's effect computes is not written at all; cells of a group whose effect
does not compute it hold NaN (bars are never slack, so their ``slack`` is
NaN), never a zero that would read as a computed value.

Files are written to a temporary name and moved into place, so an interrupted
run never leaves a half-written result behind.
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path

import meshio
import numpy as np

from .files import atomic_target

#: member results written as cell data where an effect computes them
RESULT_FIELDS = ("axial_force", "strain", "slack")


def _member_fields(system, q) -> dict[str, np.ndarray]:
    """Cell data of every member group, concatenated in group order; NaN where a group has no such result."""
    results = system.member_results(q)
    groups = system.structure.groups
    fields = {"group": np.concatenate([np.full(g.n_members, gi, dtype=np.int32) for gi, g in enumerate(groups)])
              if groups else np.zeros(0, dtype=np.int32)}
    for key in RESULT_FIELDS:
        if not any(key in results.get(g.name, {}) for g in groups):
            continue  # computed by no effect: absent
        fields[key] = np.concatenate([np.asarray(results[g.name][key], dtype=float) if key in results.get(g.name, {})
                                      else np.full(g.n_members, np.nan) for g in groups])
    return fields


def state_mesh(system, q: np.ndarray, lam: float = 1.0) -> meshio.Mesh:
    """A meshio mesh of the structure at state ``q`` with its results."""
    s = system.structure
    n = s.n_nodes
    x = q[: 3 * n].reshape(n, 3)
    conn = [g.connectivity for g in s.groups]
    lines = np.concatenate(conn) if conn else np.zeros((0, 2), dtype=np.int64)
    point_data = {
        "displacement": x - s.nodes,
        "reaction": system.reactions(q, lam)[: 3 * n].reshape(n, 3),
    }
    cell_data = {k: [v] for k, v in _member_fields(system, q).items()}
    return meshio.Mesh(points=x.copy(), cells=[("line", lines)], point_data=point_data, cell_data=cell_data)


def write_mesh(path, mesh: meshio.Mesh, file_format: str | None = None) -> Path:
    """Write any meshio mesh atomically (temporary file, then rename)."""
    path = Path(path)
    with atomic_target(path) as tmp:
        meshio.write(tmp, mesh, file_format=file_format)
    return path


def write_state(path, system, q: np.ndarray, lam: float = 1.0) -> Path:
    """Write one state (format from the suffix: ``.vtu``, ``.vtk``, ``.xdmf``, ...)."""
    return write_mesh(path, state_mesh(system, q, lam))


def write_series(path, system, states: Iterable[tuple[float, np.ndarray, float]]) -> Path:
    """Write a sequence of states as an XDMF time series.

    Parameters
    ----------
    path : path-like
        Target ``.xdmf`` file. Data are stored inline (XML), so the series is
        one self-contained file.
    states : iterable of (time, q, lam)
        ``time`` is the value ParaView shows on its time axis (a load factor,
        a prescribed displacement or a physical time).
    """
    path = Path(path)
    with atomic_target(path) as tmp, meshio.xdmf.TimeSeriesWriter(tmp, data_format="XML") as writer:
        first = True
        for t, q, lam in states:
            mesh = state_mesh(system, q, lam)
            if first:
                # XDMF series share one geometry: the reference configuration;
                # ParaView's "Warp By Vector" on displacement shows each state
                writer.write_points_cells(system.structure.nodes, mesh.cells)
                first = False
            writer.write_data(float(t), point_data=mesh.point_data, cell_data=mesh.cell_data)
    return path
