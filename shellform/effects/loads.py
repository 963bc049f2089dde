"""Constant applied forces: nodal loads and self-weight.

Both have the potential ``E = -f . q`` (a constant force does work on the
displacement), so the gradient is ``-f`` and the Hessian is empty.
"""

from __future__ import annotations

import numpy as np

from .base import Effect


class ConstantForce(Effect):
    """A fixed force vector on the DOFs.

    Parameters
    ----------
    force : ndarray, shape (n_dof,)
        Force on every DOF [N].
    scales_with_load : bool
        Multiply by the analysis load factor (reference load) or apply in full
        (dead load).
    name : str
        ``"loads"`` for nodal loads, ``"gravity"`` for self-weight.
    """

    is_external = True

    def __init__(self, force: np.ndarray, scales_with_load: bool = True, name: str = "loads"):
        super().__init__(len(force))
        self.force = np.asarray(force, dtype=float)
        self.scales_with_load = scales_with_load
        self.name = name

    def energy(self, q):
        return -float(self.force @ q)

    def gradient(self, q):
        return -self.force


def nodal_load_effects(structure) -> list[ConstantForce]:
    """The structure's nodal load cases as at most two effects (scaled and dead)."""
    effects = []
    for scaled in (True, False):
        cases = [c.forces for c in structure.load_cases if c.scaled == scaled]
        if cases:
            f = np.zeros(structure.n_dof)
            f[: 3 * structure.n_nodes] = np.sum(cases, axis=0).ravel()
            effects.append(ConstantForce(f, scales_with_load=scaled, name="loads" if scaled else "dead_loads"))
    return effects


def gravity_effect(structure, scales_with_load: bool = False) -> ConstantForce:
    """Self-weight of the lumped nodal masses under ``structure.gravity``.

    Self-weight is a dead load by default; a load-controlled analysis of the
    weight itself (for example a hanging net loaded up from zero) asks for
    ``scales_with_load=True``.
    """
    g = structure.gravity if structure.gravity is not None else np.array([0.0, 0.0, -9.81])
    f = np.zeros(structure.n_dof)
    f[: 3 * structure.n_nodes] = (structure.nodal_mass()[:, None] * g[None, :]).ravel()
    return ConstantForce(f, scales_with_load=scales_with_load, name="gravity")
