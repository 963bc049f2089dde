"""The hypostatic check of the MRA paper, Eqs. (11)-(12).

A hanging net can only find its shape by falling if it is a mechanism at the
start: the number of degrees of freedom of its multi-body model must exceed
the number of degrees of constraint,

    D.o.F = 6 n_t                                                       (12)
    D.o.C = 9 n_A + 6 n_B + 6 n_C1 + 3 n_C2 + 1 n_t                     (11)

with ``n_t`` all nodes and ``n_A``, ``n_B``, ``n_C1``, ``n_C2`` the nodes of
the constraint typologies of the paper's Fig. 2. The figure itself is not in
the text we work from, so the typologies are read as follows (the weights
are the paper's):

* A  (9): suspension points, every translation held;
* B  (6): partially held nodes (some translations held: sliding supports);
* C1 (6): free nodes on the rim of the net (fewer ropes than the full
  valence of the grid, at least two);
* C2 (3): free nodes hanging on a single rope;
* free nodes with the full valence (interior nodes) count only in ``n_t``.

Beside the paper's count we report Maxwell's count for the translational
model the solver integrates (3 DOFs per free node against one constraint per
rope); it is informative only, since slack ropes constrain nothing.

A net that is a mechanism the solver cannot handle (a part not connected to
any suspension point, or free to translate along an axis no support
restrains) raises :class:`~shellform.errors.MechanismError`.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from ..errors import MechanismError, ModelError
from ..model import Structure

WEIGHTS = {"A": 9, "B": 6, "C1": 6, "C2": 3, "t": 1}


@dataclass
class HypostaticReport:
    """Counts of Eqs. (11)-(12) and the verdict."""

    n_t: int
    n_A: int
    n_B: int
    n_C1: int
    n_C2: int
    n_interior: int
    dof: int
    doc: int
    hypostatic: bool
    maxwell_free_dof: int
    maxwell_constraints: int
    warning: str | None = None

    def as_dict(self) -> dict:
        return asdict(self)


def hypostatic_check(structure: Structure, rim: np.ndarray | None = None) -> HypostaticReport:
    """Classify the nodes, count D.o.F and D.o.C, and check for unhandled mechanisms.

    ``rim`` (the boundary nodes of an unstructured net) makes C1 the free rim
    nodes with at least two ropes: the valence of an unstructured mesh varies
    inside it, so "fewer ropes than the largest valence" would count interior
    nodes as rim nodes. A structured grid (``rim`` None) uses the valence.

    Raises
    ------
    MechanismError
        When a part of the net can translate freely (no suspension point
        restrains it) or a free node has no rope: the net would fall away.
    """
    n = structure.n_nodes
    if structure.n_twist:
        raise ModelError("hypostatic check: the structure has twist DOFs; the check applies to rope nets")
    ropes = [g for g in structure.groups]
    conn = np.concatenate([g.connectivity for g in ropes]) if ropes else np.zeros((0, 2), dtype=np.int64)
    degree = np.bincount(conn.ravel(), minlength=n)
    held = structure.constrained_mask[: 3 * n].reshape(n, 3).sum(axis=1)
    free = held == 0
    orphan = np.flatnonzero(free & (degree == 0))
    if orphan.size:
        raise MechanismError(
            f"hypostatic check: free node {int(orphan[0])} has no rope ({orphan.size} such nodes); "
            "it would fall away from the net"
        )
    structure.check_supports()  # raises MechanismError for parts that translate freely

    full = int(degree.max()) if n else 0
    n_A = int(np.sum(held == 3))
    n_B = int(np.sum((held > 0) & (held < 3)))
    n_C2 = int(np.sum(free & (degree == 1)))
    if rim is None:
        on_rim = degree < full
    else:
        on_rim = np.zeros(n, dtype=bool)
        on_rim[np.asarray(rim, dtype=np.int64)] = True
    n_C1 = int(np.sum(free & (degree >= 2) & on_rim))
    n_int = int(np.sum(free & (degree >= 2) & ~on_rim))
    dof = 6 * n
    doc = WEIGHTS["A"] * n_A + WEIGHTS["B"] * n_B + WEIGHTS["C1"] * n_C1 + WEIGHTS["C2"] * n_C2 + WEIGHTS["t"] * n
    hypostatic = dof > doc
    warning = None
    if not hypostatic:
        warning = (
            f"the net is not hypostatic: D.o.F = {dof} <= D.o.C = {doc} (Eqs. 11-12); with this many "
            "constrained nodes it cannot hang freely into its shape"
        )
    free_dof = int(3 * n - structure.constrained_mask[: 3 * n].sum())
    return HypostaticReport(
        n_t=n, n_A=n_A, n_B=n_B, n_C1=n_C1, n_C2=n_C2, n_interior=n_int, dof=dof, doc=doc,
        hypostatic=bool(hypostatic), maxwell_free_dof=free_dof, maxwell_constraints=int(len(conn)),
        warning=warning,
    )
