"""The effects a bar/rope scene lists (or calls for) and the System that holds them."""

from __future__ import annotations

import numpy as np

from ..assembly import System, member_effects
from ..effects import gravity_effect, nodal_load_effects
from ..errors import SceneError
from ..model import Structure
from .error_keys import scene_error_at


def default_effects(scene: dict) -> list[str]:
    """The effects a scene calls for when it does not list them."""
    kinds = {m["kind"] for m in scene["members"]}
    names = []
    if "bar" in kinds:
        names.append("axial")
    if "rope" in kinds:
        names.append("rope")
    if scene.get("rods") is not None:
        names.append("rods")
    if scene["loads"]:
        names.append("loads")
    if scene["gravity"] is not None:
        names.append("gravity")
    if scene["imperfection"] is not None and scene["imperfection"]["type"] == "forces":
        names.append("imperfection")
    return names


def random_forces(structure: Structure, amplitude: float, seed: int) -> np.ndarray:
    """Random dead forces on the free node translations with total norm ``amplitude``."""
    n = structure.n_nodes
    free = ~structure.constrained_mask[: 3 * n]
    g = np.random.default_rng(seed).normal(size=3 * n) * free
    f = np.zeros(structure.n_dof)
    norm = np.linalg.norm(g)
    if norm > 0:
        f[: 3 * n] = amplitude * g / norm
    return f


def _member_effects(structure: Structure) -> list:
    """The bar and rope effects of a structure; rods have theirs in their network."""
    if not any(g.kind == "rod" for g in structure.groups):
        return member_effects(structure)
    from ..assembly import AxialBar, Rope

    kinds = {"bar": AxialBar, "rope": Rope}
    effects = []
    for g in structure.groups:
        if g.kind in kinds:
            e = kinds[g.kind](structure.n_dof, g.connectivity, g.EA, g.rest_length)
            e.label = g.name
            effects.append(e)
    return effects


def scene_system(scene: dict, structure: Structure, network=None) -> System:
    """A System with exactly the effects the scene lists (or calls for).

    ``network`` is the scene's RodNetwork
    (:func:`~shellform.scene.structure.build_structure_and_rods`), required
    when the scene has rods.
    """
    from ..effects.loads import ConstantForce
    from ..effects.sliding import sliding_effects
    from .rod_layouts import has_rods

    include = (scene["effects"] or {}).get("include") or default_effects(scene)
    effects = []
    kind_of = {"axial": "bar", "rope": "rope"}
    for e in _member_effects(structure):
        group = structure.group(e.label)
        wanted = [k for k, v in kind_of.items() if v == group.kind][0]
        if wanted in include:
            effects.append(e)
    if has_rods(scene):
        if network is None:
            raise SceneError("rods", "a scene with rods builds its system from its rod network: use build_model")
        if "rods" in include:
            effects += network.effects()
    elif "rods" in include:
        raise SceneError("effects.include", "lists 'rods' but the scene has no [rods] table")
    effects += sliding_effects(structure)
    if "loads" in include:
        effects += nodal_load_effects(structure)
    if "gravity" in include:
        if structure.gravity is None:
            raise SceneError("effects.include", "lists 'gravity' but the scene has no [gravity] table")
        effects.append(gravity_effect(structure, scales_with_load=scene["gravity"]["scaled"]))
    if "imperfection" in include:
        imp = scene["imperfection"]
        if imp is None or imp["type"] != "forces":
            raise SceneError("effects.include", "lists 'imperfection' but the scene has no [imperfection] of type "
                             "'forces'")
        f = random_forces(structure, imp["amplitude"], imp["seed"])
        effects.append(ConstantForce(f, scales_with_load=False, name="imperfection"))
    with scene_error_at("supports"):
        if network is not None:
            network.check_supports()  # the structure's check, counting the penalty joints too
        return System(structure, effects, check=network is None)
