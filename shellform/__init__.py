"""shellform: form finding and post-buckling analysis of gridshells."""

from .api import Result, builtin_scenes, run, scene_from_toml
from .assembly import System, build_system
from .errors import MechanismError, ModelError, SceneError, ShellformError
from .model import Structure
from .scene import load_scene, parse_scene
from .solvers import StaticResult, solve_static

__version__ = "0.1.0"

__all__ = [
    "run",
    "Result",
    "load_scene",
    "parse_scene",
    "scene_from_toml",
    "builtin_scenes",
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
