"""Planform grids of the standard MRA cases, written as VTU quad meshes.

Writes into this folder: ``net_9x4.vtu`` (9 x 4 quads on 9 m x 4 m), ``disk_24.vtu``
(24 x 24 quads on a disc of radius 10 m), ``large_frames.vtu`` (120 x 80 quads on
30 m x 20 m) and ``nurbs_dish.vtu`` (16 x 12 quads on a B-spline dish), each with the
structured index ``(i, j)`` and a boundary flag as point data. The same grids are built
in memory by the scenes in ``validation/mra``; these files are for viewing and for other
tools.

Run:  python meshes/mra/standard_grids.py
"""

from pathlib import Path

import meshio
import numpy as np

from shellform.geometry import bspline_surface_grid, dish, disk_grid, rectangle_grid

HERE = Path(__file__).resolve().parent


def write(grid, name):
    boundary = np.zeros(grid.n_nodes)
    boundary[grid.boundary] = 1.0
    mesh = meshio.Mesh(grid.nodes, [("quad", grid.quads)],
                       point_data={"i": grid.ij[:, 0].astype(float), "j": grid.ij[:, 1].astype(float),
                                   "boundary": boundary})
    meshio.write(HERE / name, mesh)
    print(f"{name}: {grid.n_nodes} nodes, {len(grid.quads)} quads, {len(grid.edges)} edges")


if __name__ == "__main__":
    write(rectangle_grid(9.0, 4.0, 9, 4), "net_9x4.vtu")
    write(disk_grid(10.0, 24), "disk_24.vtu")
    write(rectangle_grid(30.0, 20.0, 120, 80), "large_frames.vtu")
    write(bspline_surface_grid(dish((0.0, 16.0), (0.0, 12.0), 3.0, n_ctrl=5).surface, 16, 12), "nurbs_dish.vtu")
