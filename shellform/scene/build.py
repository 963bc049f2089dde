"""A bar/rope scene built: its Structure and System, with its imperfection applied."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..assembly import System
from ..errors import SceneError
from ..model import Structure
from .system import scene_system
from .structure import build_structure_and_rods, reference_nodes, scene_start_state


@dataclass
class Model:
    """A bar/rope scene built: its structure, system and imperfection.

    Attributes
    ----------
    structure : Structure
    system : System
    imperfection : dict
        What was applied (JSON-ready; empty without an imperfection).
    network : RodNetwork or None
        The scene's rods (their twist inertia, reference frames and layout).
    """

    structure: Structure
    system: System
    imperfection: dict = field(default_factory=dict)
    network: object = None


def _scaled(delta: np.ndarray, amplitude: float, where: str) -> np.ndarray:
    """``delta`` scaled so that its largest node movement is ``|amplitude|`` (sign kept)."""
    size = np.linalg.norm(delta, axis=1).max() if len(delta) else 0.0
    if size == 0:
        raise SceneError(where, "there is no free node to move")
    return delta * (amplitude / size)


def _mode_shape(scene: dict, structure: Structure, system: System) -> tuple[np.ndarray, float]:
    """Lowest eigenmode of the free tangent (translations per node) and its eigenvalue."""
    from ..solvers import solve_static
    from ..solvers.stability import critical_modes

    imp = scene["imperfection"]
    q = system.state(base=scene_start_state(scene, structure))
    if imp["load_factor"] is not None:
        res = solve_static(system, q0=q, lam=imp["load_factor"], mu=scene["analysis"]["prescribed"])
        if not res.success:
            raise SceneError("imperfection.load_factor", f"no equilibrium at load factor {imp['load_factor']}: "
                             f"{res.message}")
        q = res.q
    values, vectors = critical_modes(system.tangent_free(q), k=1)
    full = np.zeros(structure.n_dof)
    full[system.free] = vectors[:, 0]
    return full[: 3 * structure.n_nodes].reshape(-1, 3), float(values[0])


def build_model(scene: dict) -> Model:
    """Structure and System of a bar/rope scene, with its imperfection applied."""
    structure, network = build_structure_and_rods(scene)
    system = scene_system(scene, structure, network)
    imp = scene["imperfection"]
    if imp is None or imp["type"] == "forces":
        note = {} if imp is None else {"type": "forces", "amplitude_N": imp["amplitude"], "seed": imp["seed"]}
        return Model(structure, system, note, network)
    nodes = structure.nodes
    free = ~structure.constrained_mask[: 3 * structure.n_nodes].reshape(-1, 3)
    if imp["type"] == "random":
        delta = np.random.default_rng(imp["seed"]).normal(size=nodes.shape) * free
        note = {"type": "random", "seed": imp["seed"]}
    else:
        delta, value = _mode_shape(scene, structure, system)
        note = {"type": "mode", "eigenvalue": value, "load_factor": imp["load_factor"]}
    delta = _scaled(delta, imp["amplitude"], "imperfection.amplitude")
    note.update(amplitude_m=imp["amplitude"], max_node_movement_m=float(np.linalg.norm(delta, axis=1).max()))
    # the scene's own nodes move; copies of penalty-joint nodes follow theirs
    structure, network = build_structure_and_rods(scene, (nodes + delta)[: len(reference_nodes(scene))])
    return Model(structure, scene_system(scene, structure, network), note, network)
