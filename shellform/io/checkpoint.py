"""Checkpoint files: named arrays in one ``.npz``, written atomically.

A checkpoint is written to a temporary file in the same folder and renamed
over the old one, so an interruption at any moment leaves either the previous
checkpoint or the new one, never a half-written file.
"""

from __future__ import annotations

import os
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import CheckpointMismatch
from .files import open_atomic


def save_checkpoint(path, **arrays) -> Path:
    """Write ``arrays`` (names to array-likes or scalars) to ``path`` atomically."""
    path = Path(path)
    with open_atomic(path, "wb") as fh:
        np.savez(fh, **{k: np.asarray(v) for k, v in arrays.items()})
    return path


def open_checkpoint(path):
    """``np.load`` of a checkpoint (use it in a ``with``); a file that is none is refused clearly.

    Raises
    ------
    CheckpointMismatch
        The file is not an ``.npz`` of arrays (a foreign or damaged file).
    """
    try:
        data = np.load(path, allow_pickle=False)
        if not hasattr(data, "files") or "meta" in data.files and data["meta"].dtype == object:
            raise ValueError("not an archive of arrays")
        return data
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as exc:
        raise CheckpointMismatch(f"checkpoint {path} cannot be read ({exc}); delete it or run without "
                                 "--resume") from None


def load_checkpoint(path) -> dict[str, np.ndarray] | None:
    """The arrays of a checkpoint, or None when there is none."""
    path = Path(path)
    if not path.exists():
        return None
    with open_checkpoint(path) as data:
        return {k: data[k] for k in data.files}


@dataclass(frozen=True)
class CheckpointFile:
    """A checkpoint file that a solver saves its state to (the ``checkpoint`` of
    :func:`~shellform.solvers.continuation.trace_path`).

    Attributes
    ----------
    path : path
        The ``.npz`` file.
    every : int
        Accepted steps between two saves (0: only at the end).
    resume : bool
        Continue from ``path`` when it exists.
    """

    path: str | os.PathLike
    every: int = 10
    resume: bool = False

    def exists(self) -> bool:
        return Path(self.path).exists()

    def write(self, **arrays) -> None:
        save_checkpoint(self.path, **arrays)

    def read(self):
        """The saved arrays (use in a ``with``)."""
        return open_checkpoint(self.path)

