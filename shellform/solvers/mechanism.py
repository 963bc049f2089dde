"""Which motion makes a tangent singular: the words a failed solve gives a user.

A structure that is a mechanism, or close to one, has a tangent with
eigenvalues near zero; a solver meets it as a singular factorisation or a
corrector that does not converge. Saying so is not enough to mend the model:
the user needs to see the motion. :func:`describe_soft_modes` reports the
eigenvalues nearest zero (relative to the largest stiffness) and, for each,
the nodes (or, for twist DOFs, the rod edges) that move most.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .stability import InertiaError, critical_modes

#: an eigenvalue below this fraction of the largest diagonal stiffness counts as near zero
SOFT_RATIO = 1e-8


@dataclass(frozen=True)
class SoftMode:
    """One eigenpair of the free tangent nearest zero.

    Attributes
    ----------
    eigenvalue : float
    relative : float
        Eigenvalue over the largest diagonal entry of the tangent.
    mode : ndarray (n_dof,)
        Unit eigenvector over all DOFs (zero at constrained ones).
    """

    eigenvalue: float
    relative: float
    mode: np.ndarray


def soft_modes(system, K, k: int = 3) -> list[SoftMode]:
    """The ``k`` eigenpairs of the free tangent ``K`` nearest zero (empty if they cannot be computed)."""
    try:
        w, V = critical_modes(K, k)
    except (InertiaError, ValueError, RuntimeError):
        return []
    top = float(np.max(np.abs(K.diagonal()), initial=0.0)) or 1.0
    modes = []
    for j in range(len(w)):
        full = np.zeros(system.n_dof)
        full[system.free] = V[:, j]
        modes.append(SoftMode(float(w[j]), float(w[j]) / top, full))
    return modes


def moving_parts(system, mode: np.ndarray, most: int = 6) -> str:
    """The nodes (and rod edges, by their twist DOF) that move most in ``mode``, in words."""
    n_nodes = system.structure.n_nodes
    nodal = np.linalg.norm(mode[: 3 * n_nodes].reshape(-1, 3), axis=1)
    twist = np.abs(mode[3 * n_nodes:])
    items = [(a, f"node {i}") for i, a in enumerate(nodal)] + [(a, f"edge twist {i}") for i, a in enumerate(twist)]
    values = np.array([a for a, _ in items])
    order = np.argsort(-values)[:most]
    peak = float(values[order[0]]) if len(order) else 0.0
    shown = [f"{items[i][1]} ({values[i] / peak:.2f})" for i in order if peak > 0 and values[i] >= 0.05 * peak]
    return ", ".join(shown)


def describe_soft_modes(system, K, k: int = 3) -> str:
    """A sentence naming the near-zero stiffness modes of ``K`` and what moves in them ('' if none are near zero)."""
    modes = [m for m in soft_modes(system, K, k) if abs(m.relative) <= SOFT_RATIO]
    if not modes:
        return ""
    parts = [f"eigenvalue {m.eigenvalue:.3e} ({m.relative:.1e} of the largest stiffness), moving "
             f"{moving_parts(system, m.mode)}" for m in modes]
    kind = "a mode" if len(modes) == 1 else f"{len(modes)} modes"
    return (f"the tangent has {kind} of near-zero stiffness (a mechanism or a structure at a critical point): "
            + "; ".join(parts) + ". Restrain these motions (supports, bracing members) or start from a loaded state")
