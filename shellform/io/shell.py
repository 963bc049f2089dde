"""A found form as a surface: the faces of a net as a mesh of their own.

:func:`surface_mesh` makes a surface mesh (quad or triangle cells only) with
point data and the area of every face, for ParaView, Rhino (through
:func:`shellform.io.rhino.write_3dm`) or any mesher.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import meshio
import numpy as np

from .mesh import write_mesh


def face_areas(points: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Area of every planar or warped quad (two triangles on the 0-2 diagonal) or triangle."""
    p = np.asarray(points, dtype=float)[np.asarray(faces)]
    area = 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1)
    if p.shape[1] == 4:
        area += 0.5 * np.linalg.norm(np.cross(p[:, 2] - p[:, 0], p[:, 3] - p[:, 0]), axis=1)
    return area


def surface_mesh(points, faces, point_data: Mapping[str, np.ndarray] | None = None) -> meshio.Mesh:
    """A surface mesh of quad (``faces`` with 4 columns) or triangle cells, or of both (a sequence of such
    arrays: the quads and the triangles a mesher leaves among them).

    Cell data: ``area`` of every face. Point data as given.
    """
    several = isinstance(faces, (list, tuple)) and all(isinstance(f, np.ndarray) and f.ndim == 2 for f in faces)
    blocks = list(faces) if several else [faces]
    blocks = [np.asarray(f, dtype=np.int64) for f in blocks if len(f)]
    points = np.asarray(points, dtype=float)
    return meshio.Mesh(points=points.copy(), cells=[({3: "triangle", 4: "quad"}[f.shape[1]], f) for f in blocks],
                       point_data={k: np.asarray(v) for k, v in (point_data or {}).items()},
                       cell_data={"area": [face_areas(points, f) for f in blocks]})


def write_surface(path, points, faces, point_data=None) -> Path:
    """Write :func:`surface_mesh` (format from the suffix, e.g. ``.vtu``) atomically."""
    return write_mesh(path, surface_mesh(points, faces, point_data))
