"""Output, the only writer of files: meshio meshes, JSON summaries, tables and plots, checkpoints.

Every file goes through :mod:`shellform.io.files` (a temporary file renamed over
the target, the umask's mode); :func:`shellform.io.files.output_lock` keeps one
run per output folder.
"""

from .mesh import state_mesh, write_mesh, write_mode, write_state
from .xdmf import write_series
from .summary import write_json

__all__ = ["state_mesh", "write_mesh", "write_mode", "write_series", "write_state", "write_json"]
