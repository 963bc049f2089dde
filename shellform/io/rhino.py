"""Rhino ``.3dm`` export (optional extra: ``pip install shellform[rhino]``).

Members become line curves, rod centrelines polylines and surfaces (the
inverted shell of a form-found net) meshes, each on a named layer, so the
result opens in Rhino and feeds Grasshopper.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from .files import atomic_target


def _rhino():
    try:
        import rhino3dm
    except ImportError:  # pragma: no cover
        raise ImportError("Rhino export needs rhino3dm: pip install 'shellform[rhino]'") from None
    return rhino3dm


def write_3dm(
    path,
    lines: dict[str, tuple[np.ndarray, np.ndarray]] | None = None,
    polylines: dict[str, Sequence[np.ndarray]] | None = None,
    meshes: dict[str, tuple[np.ndarray, np.ndarray]] | None = None,
) -> Path:
    """Write geometry to a Rhino file (atomically).

    Parameters
    ----------
    lines : dict layer -> (points (n, 3), connectivity (m, 2))
    polylines : dict layer -> list of (k, 3) point arrays
    meshes : dict layer -> (points (n, 3), faces (f, 3 or 4))
    """
    r3 = _rhino()
    model = r3.File3dm()
    model.Settings.ModelUnitSystem = r3.UnitSystem.Meters

    def layer(name):
        lay = r3.Layer()
        lay.Name = name
        index = model.Layers.Add(lay)
        attrs = r3.ObjectAttributes()
        attrs.LayerIndex = index
        return attrs

    for name, (pts, conn) in (lines or {}).items():
        attrs = layer(name)
        for a, b in np.asarray(conn):
            model.Objects.AddLine(r3.Point3d(*map(float, pts[a])), r3.Point3d(*map(float, pts[b])), attrs)
    for name, curves in (polylines or {}).items():
        attrs = layer(name)
        for pts in curves:
            pl = r3.Point3dList()
            for p in np.asarray(pts, dtype=float):
                pl.Add(*p)
            model.Objects.AddPolyline(pl, attrs)
    for name, (pts, faces) in (meshes or {}).items():
        attrs = layer(name)
        mesh = r3.Mesh()
        for p in np.asarray(pts, dtype=float):
            mesh.Vertices.Add(*p)
        for f in np.asarray(faces, dtype=int):
            mesh.Faces.AddFace(*map(int, f))
        mesh.Normals.ComputeNormals()
        model.Objects.AddMesh(mesh, attrs)
    path = Path(path)
    with atomic_target(path) as tmp:
        if not model.Write(str(tmp), 7):
            raise OSError(f"rhino3dm could not write {path}")
    return path


def structure_3dm(path, system, q: np.ndarray) -> Path:
    """Every member group of a structure at state ``q`` as line curves, one layer per group."""
    s = system.structure
    x = q[: 3 * s.n_nodes].reshape(-1, 3)
    return write_3dm(path, lines={g.name: (x, g.connectivity) for g in s.groups})
