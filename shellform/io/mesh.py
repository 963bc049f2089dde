"""meshio export of states and state sequences (ParaView reads both).

Members are written as line cells in one block, nodes as points at their
current position. Point data: ``displacement`` and ``reaction``. Cell data:
``axial_force``, ``strain``, ``slack`` (1 for a slack rope) and ``group`` (the
member group number, in the order the groups were added).

Files are written to a temporary name and moved into place, so an interrupted
run never leaves a half-written result behind.
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path

import meshio
import numpy as np

from .files import atomic_target

CELL_FIELDS = ("axial_force", "strain", "slack", "group")


def _member_fields(system, q) -> dict[str, np.ndarray]:
    """Cell data of every member group, concatenated in group order."""
    results = system.member_results(q)
    fields = {k: [] for k in CELL_FIELDS}
    for gi, g in enumerate(system.structure.groups):
        res = results.get(g.name, {})
        m = g.n_members
        fields["axial_force"].append(res.get("axial_force", np.zeros(m)))
        fields["strain"].append(res.get("strain", np.zeros(m)))
        fields["slack"].append(res.get("slack", np.zeros(m, dtype=np.int8)).astype(np.int32))
        fields["group"].append(np.full(m, gi, dtype=np.int32))
    return {k: np.concatenate(v) if v else np.zeros(0) for k, v in fields.items()}


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
