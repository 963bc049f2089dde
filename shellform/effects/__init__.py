"""Physical effects: one energy term each, with gradient and sparse Hessian."""

from .axial import AxialBar, Rope
from .base import Effect
from .loads import ConstantForce, gravity_effect, nodal_load_effects

__all__ = ["Effect", "AxialBar", "Rope", "ConstantForce", "gravity_effect", "nodal_load_effects"]
