"""A small triangulated lattice dome, written as ``lattice_dome.obj``.

Rings of nodes on a shallow spherical cap: ring ``k`` (k = 0..3) has ``6 k``
nodes at plan radius ``k a`` (one apex node for k = 0), ``a = 0.5 m``, so the
rim (k = 3) lies on the circle of radius 1.5 m at z = 0. The plan is
triangulated (Delaunay) and lifted onto a sphere of radius 3 m: rise 0.40 m.
37 nodes, 90 edges, 54 triangles. Scenes read it with
``[geometry] type = "file"`` and support the rim by ``z = 0.0``.

Run:  python meshes/lattice_dome.py
"""

from pathlib import Path

import meshio
import numpy as np
from scipy.spatial import Delaunay

HERE = Path(__file__).resolve().parent
RINGS, SPACING, SPHERE = 3, 0.5, 3.0


def lattice_dome():
    plan = [np.zeros((1, 2))]
    for k in range(1, RINGS + 1):
        phi = 2 * np.pi * np.arange(6 * k) / (6 * k)
        plan.append(k * SPACING * np.column_stack([np.cos(phi), np.sin(phi)]))
    plan = np.concatenate(plan)
    r = np.linalg.norm(plan, axis=1)
    rim = RINGS * SPACING
    z = np.sqrt(SPHERE**2 - r**2) - np.sqrt(SPHERE**2 - rim**2)
    z[np.isclose(r, rim)] = 0.0
    triangles = Delaunay(plan).simplices
    return np.column_stack([plan, z]), triangles


if __name__ == "__main__":
    points, triangles = lattice_dome()
    meshio.write(HERE / "lattice_dome.obj", meshio.Mesh(points, [("triangle", triangles)]))
    edges = np.unique(np.sort(np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]]),
                              axis=1), axis=0)
    print(f"lattice_dome.obj: {len(points)} nodes, {len(edges)} edges, {len(triangles)} triangles, "
          f"rise {points[:, 2].max():.3f} m")
