"""Writes rod_gridshell.obj: the quad mesh of the rod gridshell scene (scenes/rod_gridshell.toml).

A 4 m x 4 m square plan divided into 8 x 8 quads, lifted on z = rise cos(pi x / L) cos(pi y / L)
(zero on the edges, 0.8 m at the centre).

Run:  python meshes/rod_gridshell.py
"""

from pathlib import Path

import meshio
import numpy as np

HERE = Path(__file__).resolve().parent

L, N, RISE = 4.0, 8, 0.8


def gridshell_mesh(length: float = L, n: int = N, rise: float = RISE) -> meshio.Mesh:
    s = np.linspace(-length / 2, length / 2, n + 1)
    x, y = np.meshgrid(s, s, indexing="ij")
    z = rise * np.cos(np.pi * x / length) * np.cos(np.pi * y / length)
    points = np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1)
    idx = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    quads = np.stack([idx[:-1, :-1], idx[1:, :-1], idx[1:, 1:], idx[:-1, 1:]], axis=2).reshape(-1, 4)
    return meshio.Mesh(points, [("quad", quads)])


if __name__ == "__main__":
    meshio.write(HERE / "rod_gridshell.obj", gridshell_mesh())
