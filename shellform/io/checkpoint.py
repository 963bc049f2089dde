"""Checkpoint files: named arrays in one ``.npz``, written atomically.

A checkpoint is written to a temporary file in the same folder and renamed
over the old one, so an interruption at any moment leaves either the previous
checkpoint or the new one, never a half-written file.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import numpy as np


def save_checkpoint(path, **arrays) -> Path:
    """Write ``arrays`` (names to array-likes or scalars) to ``path`` atomically."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}-", suffix=".npz", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            np.savez(fh, **{k: np.asarray(v) for k, v in arrays.items()})
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
    return path


def load_checkpoint(path) -> dict[str, np.ndarray] | None:
    """The arrays of a checkpoint, or None when there is none."""
    path = Path(path)
    if not path.exists():
        return None
    with np.load(path, allow_pickle=False) as data:
        return {k: data[k] for k in data.files}
