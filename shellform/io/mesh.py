"""meshio export of states and state sequences (ParaView reads both).

Members are written as line cells in one block, nodes as points at their
current position. Point data: ``displacement`` and ``reaction``. Cell data:
``group`` (the member group number, in the order the groups were added; -1 on
a joint) and the results the effects compute on their cells
(:meth:`~shellform.effects.base.Effect.line_results`):

* bars and ropes: ``axial_force`` [N], ``strain`` [-], ropes ``slack`` (1 slack, 0 taut);
* rods, per edge: ``axial_force``, ``strain``, ``bending_moment_1``,
  ``bending_moment_2`` (about the material directors ``m1``, ``m2``) and
  ``bending_moment`` [N m], ``curvature_1``, ``curvature_2`` [1/m],
  ``torque`` [N m], ``twist_rate`` [rad/m]: hinge values interpolated to the
  edge midpoints (:mod:`shellform.effects.rod_output`);
* penalty joints, as line cells of their own between the two joined nodes:
  ``joint_force`` [N] and ``joint_gap`` [m].

A result that no effect computes is not written at all; cells whose effect
does not compute it hold NaN (bars are never slack, so their ``slack`` is
NaN), never a zero that would read as a computed value.

Files are written to a temporary name and moved into place, so an interrupted
run never leaves a half-written result behind.
"""

from __future__ import annotations

from contextlib import contextmanager
from pathlib import Path

import meshio
import numpy as np

from .files import atomic_target

def _pair_keys(cells: np.ndarray, n_nodes: int) -> np.ndarray:
    cells = np.sort(np.asarray(cells, dtype=np.int64), axis=1)
    return cells[:, 0] * n_nodes + cells[:, 1]


def _rows_of(effect, res, groups, offsets, lines, n_nodes) -> np.ndarray:
    """The member rows an effect's line results belong to."""
    names = [g.name for g in groups]
    label = getattr(effect, "label", None)
    if label in names:
        gi = names.index(label)
        return np.arange(offsets[gi], offsets[gi + 1])
    candidates = np.concatenate([np.arange(offsets[i], offsets[i + 1]) for i, g in enumerate(groups)
                                 if g.kind == res.kind] or [np.zeros(0, dtype=np.int64)])
    keys = _pair_keys(lines[candidates], n_nodes)
    order = np.argsort(keys, kind="stable")
    want = _pair_keys(res.cells, n_nodes)
    pos = np.minimum(np.searchsorted(keys[order], want), max(len(keys) - 1, 0))
    if len(keys) == 0 or np.any(keys[order][pos] != want):
        raise ValueError(f"effect {effect.name!r} reports results on {res.kind} cells that are no member "
                         "of the structure")
    return candidates[order][pos]


def _line_cells(system, q) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Line cells (members, then joints) and their cell data; NaN where a cell has no such result."""
    s = system.structure
    groups = s.groups
    offsets = np.cumsum([0] + [g.n_members for g in groups])
    lines = (np.concatenate([g.connectivity for g in groups]) if groups else np.zeros((0, 2), dtype=np.int64))
    group = np.concatenate([np.full(g.n_members, gi, dtype=np.int32) for gi, g in enumerate(groups)]
                           ) if groups else np.zeros(0, dtype=np.int32)
    fields: dict[str, np.ndarray] = {}
    joints = []
    for e in system.effects:
        res = e.line_results(q)
        if res is None:
            continue
        if res.kind == "joint":
            joints.append(res)
            continue
        rows = _rows_of(e, res, groups, offsets, lines, s.n_nodes)
        for key, value in res.fields.items():
            fields.setdefault(key, np.full(len(lines), np.nan))[rows] = value
    if joints:
        pairs = np.concatenate([j.cells for j in joints])
        fields = {k: np.concatenate([v, np.full(len(pairs), np.nan)]) for k, v in fields.items()}
        start = len(lines)
        lines = np.concatenate([lines, pairs])
        group = np.concatenate([group, np.full(len(pairs), -1, dtype=np.int32)])
        for j in joints:
            for key, value in j.fields.items():
                fields.setdefault(key, np.full(len(lines), np.nan))[start:start + len(j.cells)] = value
            start += len(j.cells)
    return lines, {"group": group, **fields}


def state_mesh(system, q: np.ndarray, lam: float = 1.0, history=None) -> meshio.Mesh:
    """A meshio mesh of the structure at state ``q`` with its results.

    ``history``: the path history ``q`` was found with (``system.history()``
    when the state was accepted); a rod model's twists, moments, torques and
    reactions are evaluated with it. None: the system's current history, right
    for the last accepted state only.
    """
    s = system.structure
    n = s.n_nodes
    x = q[: 3 * n].reshape(n, 3)
    with evaluated_with(system, history):
        lines, fields = _line_cells(system, q)
        reactions = system.reactions(q, lam)[: 3 * n].reshape(n, 3)
    point_data = {
        "displacement": x - s.nodes,
        "reaction": reactions,
    }
    cell_data = {k: [v] for k, v in fields.items()}
    return meshio.Mesh(points=x.copy(), cells=[("line", lines)], point_data=point_data, cell_data=cell_data)


def normalised_mode(mode: np.ndarray, n_nodes: int) -> np.ndarray:
    """The translational part of a mode, shape (n_nodes, 3), scaled to a largest nodal
    displacement of 1 and signed so that its largest component is positive."""
    m = np.asarray(mode[: 3 * n_nodes], dtype=float).reshape(n_nodes, 3)
    size = np.linalg.norm(m, axis=1).max() if n_nodes else 0.0
    if size == 0.0:
        return m  # a mode of the twist angles alone moves no node
    flat = m.ravel()
    return m * (np.sign(flat[np.argmax(np.abs(flat))]) / size)


def write_mode(path, system, q: np.ndarray, mode: np.ndarray, lam: float = 1.0, history=None) -> Path:
    """Write the state at a critical point with its buckling mode as point data ``mode``.

    ``mode`` is normalised by :func:`normalised_mode` (ParaView: "Warp By
    Vector" on ``mode`` with a scale factor in metres shows the buckled shape);
    ``history`` as in :func:`state_mesh`.
    """
    mesh = state_mesh(system, q, lam, history)
    mesh.point_data["mode"] = normalised_mode(mode, system.structure.n_nodes)
    return write_mesh(path, mesh)


def write_mesh(path, mesh: meshio.Mesh, file_format: str | None = None) -> Path:
    """Write any meshio mesh atomically (temporary file, then rename)."""
    path = Path(path)
    with atomic_target(path) as tmp:
        meshio.write(tmp, mesh, file_format=file_format)
    return path


def write_state(path, system, q: np.ndarray, lam: float = 1.0, history=None) -> Path:
    """Write one state (format from the suffix: ``.vtu``, ``.vtk``, ``.xdmf``, ...); ``history`` as in
    :func:`state_mesh`."""
    return write_mesh(path, state_mesh(system, q, lam, history))


@contextmanager
def evaluated_with(system, history):
    """``system`` with the path history ``history`` while the block runs (systems without history as they are)."""
    if history is None or not hasattr(system, "evaluated_with"):
        yield system
        return
    with system.evaluated_with(history):
        yield system
