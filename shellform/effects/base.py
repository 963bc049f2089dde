"""The common face of every physical effect.

An effect is one energy term of the total potential, vectorised over all the
members that carry it. It exposes

* ``energy(q) -> float``
* ``gradient(q) -> ndarray (n_dof,)``
* ``hessian_pattern() -> (rows, cols)``: fixed for the life of the effect,
* ``hessian_values(q) -> vals``: in the order of ``hessian_pattern``,
* optionally ``hessian_upper_pattern()`` and ``hessian_upper_values(q)``:
  the upper triangles of symmetric element blocks only,

so that a :class:`~shellform.assembly.System` computes the sparsity pattern
once and only scatters values afterwards. ``hessian(q)`` returns the COO
triplets for convenience (tests, small problems).

An effect that represents an applied load sets ``scales_with_load = True``; the
System multiplies its contribution by the load factor of the analysis.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class LineResults:
    """Results an effect reports on line cells (two nodes each), for output files.

    Attributes
    ----------
    cells : ndarray (m, 2)
        End nodes of every cell the results belong to.
    kind : str
        The member kind of those cells (``"bar"``, ``"rope"``, ``"rod"``), or
        ``"joint"`` for node pairs that are no member of the structure.
    fields : dict of name -> ndarray (m,)
        One value per cell. Only quantities the effect computes appear.
    """

    cells: np.ndarray
    kind: str
    fields: dict[str, np.ndarray]


class Effect:
    """Base class: one energy term with its gradient and sparse Hessian."""

    #: short name used in scenes, messages and output
    name: str = "effect"
    #: multiply this effect by the analysis load factor (applied loads)
    scales_with_load: bool = False
    #: an applied load (constant force) rather than an internal energy
    is_external: bool = False

    def __init__(self, n_dof: int):
        self.n_dof = int(n_dof)

    def energy(self, q: np.ndarray) -> float:
        raise NotImplementedError

    def gradient(self, q: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def hessian_pattern(self) -> tuple[np.ndarray, np.ndarray]:
        """Row and column indices of the Hessian entries (duplicates allowed)."""
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)

    def hessian_values(self, q: np.ndarray) -> np.ndarray:
        """Hessian entries in the order of :meth:`hessian_pattern`."""
        return np.zeros(0)

    def hessian_upper_pattern(self) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """The Hessian by the entries on and above the diagonal of its element blocks, or None (the default).

        An effect whose Hessian is made of symmetric element blocks can list
        each block's upper triangle only: half the values to compute and to
        scatter. Returns ``(rows, cols, mirrored)``: the entry of each value,
        and whether it also stands for its transpose (an entry off its block's
        diagonal; one that lands on the global diagonal, from a DOF repeated
        in a block, then counts twice). The System assembles such an effect's
        share of the tangent from :meth:`hessian_upper_values`; the full
        :meth:`hessian_pattern` and :meth:`hessian_values` stay the reference
        for everything else.
        """
        return None

    def hessian_upper_values(self, q: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """Hessian values in the order of :meth:`hessian_upper_pattern`, written to ``out`` when given."""
        raise NotImplementedError(f"effect {self.name!r} has no upper-triangle Hessian values")

    @classmethod
    def summed_hessian_upper_values(cls, effects, q: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """The sum of the :meth:`hessian_upper_values` of ``effects``, which share one upper pattern.

        Called on the class of the first effect; a class whose effects share
        work (the bending and twisting of the same rod hinges) overrides it.
        """
        out = effects[0].hessian_upper_values(q, out)
        for e in effects[1:]:
            out += e.hessian_upper_values(q)
        return out

    def hessian(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Hessian as COO triplets ``(rows, cols, vals)``."""
        rows, cols = self.hessian_pattern()
        return rows, cols, self.hessian_values(q)

    def force_magnitudes(self, q: np.ndarray) -> np.ndarray:
        """Per DOF, the sum of the magnitudes of the force contributions of every member.

        The gradient sums members' forces that balance each other; this sums
        their sizes instead, and so measures the forces in play at each DOF: the
        scale against which an equilibrium residual is judged (a pre-stressed
        net under no load still has forces in play). The default, the magnitude
        of the effect's gradient, is right for an effect whose DOFs each get one
        contribution (applied forces) and a lower bound otherwise, so it can only
        make a convergence test stricter.
        """
        return np.abs(self.gradient(q))

    def member_results(self, q: np.ndarray) -> dict[str, np.ndarray]:
        """Per-member quantities for output (axial force, strain, ...); none by default."""
        return {}

    def line_results(self, q: np.ndarray) -> LineResults | None:
        """The results this effect writes on line cells; None (the default) writes nothing."""
        return None

    def held_measures(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """Measures (member lengths) that a Newton step holds to their linearised change.

        A stiff member stores a large energy in a small change of such a
        measure, so a straight Newton step, which changes it to second order,
        is cut short by the line search. The stretch projection of
        :func:`~shellform.solvers.newton.solve_static` moves the trial state
        back onto the linearised values.

        Returns
        -------
        values : ndarray (m,)
        dofs : ndarray (m, k)
            Global DOFs each measure depends on.
        gradients : ndarray (m, k)
            Derivatives of each measure with respect to its DOFs.

        None (the default): the effect has no such measure.
        """
        return None


def element_pattern(dofs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """COO pattern of dense element blocks.

    Parameters
    ----------
    dofs : ndarray, shape (m, k)
        Global DOF indices of each element.

    Returns
    -------
    rows, cols : ndarray, shape (m * k * k,)
        Indices in the order of a C-contiguous ``(m, k, k)`` value array.
    """
    m, k = dofs.shape
    rows = np.broadcast_to(dofs[:, :, None], (m, k, k)).ravel()
    cols = np.broadcast_to(dofs[:, None, :], (m, k, k)).ravel()
    return rows.astype(np.int64), cols.astype(np.int64)


def scatter(n_dof: int, dofs: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Sum element vectors ``values`` (m, k) into a global vector at ``dofs`` (m, k)."""
    return np.bincount(dofs.ravel(), weights=values.ravel(), minlength=n_dof)
