"""Output: meshio meshes, JSON summaries."""

from .mesh import state_mesh, write_mesh, write_series, write_state
from .summary import write_json

__all__ = ["state_mesh", "write_mesh", "write_series", "write_state", "write_json"]
