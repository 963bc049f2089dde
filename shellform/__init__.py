"""shellform: form finding and post-buckling analysis of gridshells."""

from .assembly import System, build_system
from .errors import MechanismError, ModelError, SceneError, ShellformError
from .model import Structure
from .solvers import StaticResult, solve_static

__version__ = "0.1.0"

__all__ = [
    "Structure",
    "System",
    "build_system",
    "solve_static",
    "StaticResult",
    "ShellformError",
    "ModelError",
    "MechanismError",
    "SceneError",
]
