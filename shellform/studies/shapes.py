"""Imperfection shapes: buckling modes of the perfect structure, random combinations of them, random fields.

A shape is a node movement field (one row ``[dx, dy, dz]`` per node, zero
at supported components) scaled to a largest node movement of 1; a sample
moves the stress-free nodes by ``sign x amplitude x reference length``
times its shape.

- **modes**: the eigenvectors of the free tangent stiffness with the
  eigenvalues closest to zero at the perfect structure's first critical
  point (its buckling modes: the first is the critical mode);
- **mode combinations**: ``sum_i w_i phi_i`` with independent standard
  normal weights ``w_i`` over the modes ``phi_i`` (each of largest movement 1);
- **random fields**: every free component an independent zero-mean Gaussian
  field over the nodes with the squared-exponential correlation
  ``exp(-d^2 / (2 l^2))`` of two nodes a distance ``d`` apart.

The ``j``-th random shape of every amplitude comes from the generator seeded
with ``(seed, j)``: each amplitude scales the same shapes, and a sample has
the same shape however many run and in whatever order, so a resumed study
recomputes nothing it had.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import SceneError

#: nodes beyond which the random field's dense covariance (n^2 numbers, an n^3 factorisation) is refused
MAX_FIELD_NODES = 20_000


@dataclass(frozen=True)
class Sample:
    """One imperfect structure of a study."""

    index: int
    #: the shape's name: ``mode_1``, ``combination``, ``field``
    shape: str
    #: +1 or -1 (a mode's direction; random shapes +1)
    sign: int
    #: multiple of the reference length
    amplitude: float
    #: the random shape's number within its amplitude (-1 for a mode)
    draw: int = -1

    @property
    def name(self) -> str:
        return f"sample_{self.index:05d}"


def free_node_mask(structure) -> np.ndarray:
    """(n_nodes, 3) bool: the translations that are neither fixed nor prescribed."""
    return ~structure.constrained_mask[: 3 * structure.n_nodes].reshape(-1, 3)


def unit_shape(delta: np.ndarray, what: str) -> np.ndarray:
    """``delta`` scaled to a largest node movement of 1 (its largest component made positive)."""
    size = np.linalg.norm(delta, axis=1).max() if len(delta) else 0.0
    if not np.isfinite(size) or size == 0.0:
        raise SceneError("study.shapes", f"the {what} moves no node (every node is supported?)")
    flat = delta.ravel()
    sign = np.sign(flat[np.argmax(np.abs(flat))]) or 1.0
    return delta * (sign / size)


def reference_length(structure, relative_to: str) -> float:
    """The length amplitudes are multiples of: the span in plan, the mean member length, or 1 m."""
    if relative_to == "absolute":
        return 1.0
    if relative_to == "member_length":
        lengths = np.concatenate([g.rest_length for g in structure.groups if g.n_members])
        return float(np.mean(lengths))
    plan = structure.nodes[:, :2]
    if len(plan) > 4000:  # the hull's points are enough for the largest distance
        from scipy.spatial import ConvexHull

        plan = plan[ConvexHull(plan).vertices]
    d = np.sqrt(((plan[:, None, :] - plan[None, :, :]) ** 2).sum(-1)).max()
    if d == 0.0:
        raise SceneError("study.relative_to", "the nodes span nothing in plan (x, y); use member_length or absolute")
    return float(d)


def mode_shapes(system, q, k: int) -> tuple[np.ndarray, np.ndarray]:
    """The ``k`` eigenpairs of the free tangent at ``q`` closest to zero, as unit node movement fields.

    Returns
    -------
    values : ndarray (k,)
        Eigenvalues (N/m), smallest magnitude first.
    shapes : ndarray (k, n_nodes, 3)
    """
    from ..solvers.stability import critical_modes

    n_nodes = system.structure.n_nodes
    k = min(k, system.n_free)
    values, vectors = critical_modes(system.tangent_free(q), k=k)
    shapes = []
    for i in range(vectors.shape[1]):
        full = np.zeros(system.structure.n_dof)
        full[system.free] = vectors[:, i]
        shapes.append(unit_shape(full[: 3 * n_nodes].reshape(-1, 3), f"mode {i + 1}"))
    return np.asarray(values), np.asarray(shapes)


def field_factor(nodes: np.ndarray, correlation_length: float) -> np.ndarray:
    """A factor ``F`` (n, r) of the nodes' correlation matrix ``C = F F^T`` (its non-negligible eigenpairs)."""
    n = len(nodes)
    if n > MAX_FIELD_NODES:
        raise SceneError("study.shapes", f"a random field over {n} nodes needs a dense {n} x {n} covariance; at "
                         f"most {MAX_FIELD_NODES} nodes are supported")
    d2 = ((nodes[:, None, :] - nodes[None, :, :]) ** 2).sum(-1)
    C = np.exp(-d2 / (2.0 * correlation_length**2))
    w, V = np.linalg.eigh(C)
    keep = w > 1e-12 * w.max()
    return V[:, keep] * np.sqrt(w[keep])


def random_shape(settings, draw: int, modes: np.ndarray | None, factor: np.ndarray | None,
                 free: np.ndarray) -> np.ndarray:
    """The unit shape of the ``draw``-th random sample of an amplitude (see the module's note on seeds)."""
    rng = np.random.default_rng([settings.seed, draw])
    if settings.shapes == "mode_combinations":
        w = rng.standard_normal(len(modes))
        return unit_shape(np.tensordot(w, modes, axes=1) * free, "mode combination")
    z = rng.standard_normal((factor.shape[1], 3))
    return unit_shape((factor @ z) * free, "random field")


def study_samples(settings) -> list[Sample]:
    """Every sample of a study, numbered in a fixed order (amplitude, then shape and sign, or draw)."""
    out = []
    for amplitude in settings.amplitudes:
        if settings.random:
            name = "combination" if settings.shapes == "mode_combinations" else "field"
            out += [Sample(len(out) + j, name, 1, amplitude, j) for j in range(settings.samples)]
            continue
        for m in range(settings.modes):
            for sign in settings.signs:
                out.append(Sample(len(out), f"mode_{m + 1}", sign, amplitude))
    return out
