"""Writes form_found_gridshell.obj: a square gridshell whose shape is found by MRA.

A 6 m x 6 m square planform of 12 x 12 quads hung from its whole boundary (ropes 5 % slack,
the default rope weights) relaxes by MRA; the hanging net, inverted about the plane of its
supports, is a shell in pure compression under the same weight. Its quads are the mesh of the
form-found timber gridshell of scenes/form_found_gridshell.toml.

Run:  python meshes/form_found_gridshell.py
"""

from pathlib import Path

import meshio

from shellform.geometry.grids import rectangle_grid
from shellform.mra import form_find, hanging_net, invert

HERE = Path(__file__).resolve().parent
SIDE, CELLS, SLACK = 6.0, 12, 0.05


def form_found_gridshell() -> meshio.Mesh:
    grid = rectangle_grid(SIDE, SIDE, CELLS, CELLS, origin=(-SIDE / 2, -SIDE / 2, 0.0))
    found = form_find(hanging_net(grid, {"groups": ["boundary"]}, slack=SLACK))
    if not found.converged:
        raise SystemExit(f"form finding did not converge: {found.message}")
    shell = invert(found)
    return meshio.Mesh(shell.structure.nodes, [("quad", grid.quads)])


if __name__ == "__main__":
    mesh = form_found_gridshell()
    meshio.write(HERE / "form_found_gridshell.obj", mesh)
    print(f"{len(mesh.points)} nodes, {len(mesh.cells[0].data)} quads, rise {mesh.points[:, 2].max():.3f} m")
