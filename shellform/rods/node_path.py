"""Nodes moved along a prescribed path: supports that follow a function of time or a step parameter."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..errors import ModelError
from ..model import Structure


class NodePath:
    """Nodes moved along a prescribed path: positions as a function of a parameter.

    Parameters
    ----------
    dofs : ndarray (k,)
        Flat DOF indices that follow the path.
    values : callable
        ``values(t) -> ndarray (k,)``: the DOF values at path parameter ``t``
        (time for dynamics, a step parameter for statics).

    Notes
    -----
    The DOFs must be constrained in the structure (``fix_dofs``); solvers then
    overwrite their values with ``values(t)`` instead of the reference value.
    """

    def __init__(self, dofs, values: Callable[[float], np.ndarray]):
        self.dofs = np.asarray(dofs, dtype=np.int64).ravel()
        self._values = values

    def __call__(self, t: float) -> np.ndarray:
        v = np.asarray(self._values(t), dtype=float).ravel()
        if v.shape != self.dofs.shape:
            raise ModelError(f"node path: expected {self.dofs.size} values at t={t}, got {v.size}")
        return v

    @classmethod
    def waypoints(cls, structure: Structure, nodes, times, positions) -> NodePath:
        """Piecewise-linear motion of ``nodes`` through ``positions`` (T, len(nodes), 3) at ``times`` (T,).

        Before the first time the nodes sit at the first waypoint, after the
        last at the last one. The nodes' translations are fixed in the
        structure.
        """
        nodes = np.atleast_1d(np.asarray(nodes, dtype=np.int64))
        times = np.asarray(times, dtype=float)
        pos = np.asarray(positions, dtype=float).reshape(len(times), len(nodes) * 3)
        if np.any(np.diff(times) <= 0):
            raise ModelError("node path: waypoint times must increase strictly")
        dofs = structure.node_dofs(nodes).ravel()
        structure.fix_dofs(dofs)

        def values(t):
            return np.array([np.interp(t, times, pos[:, k]) for k in range(pos.shape[1])])

        return cls(dofs, values)

    @classmethod
    def curve(cls, structure: Structure, nodes, positions: Callable[[float], np.ndarray]) -> NodePath:
        """Nodes following ``positions(t) -> (len(nodes), 3)``; their translations are fixed in the structure."""
        nodes = np.atleast_1d(np.asarray(nodes, dtype=np.int64))
        dofs = structure.node_dofs(nodes).ravel()
        structure.fix_dofs(dofs)
        return cls(dofs, lambda t: np.asarray(positions(t), dtype=float).ravel())
