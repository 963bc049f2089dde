"""Geometry: structured quad grids (gmsh), B-spline surfaces, Chebyshev nets.

gmsh is imported only when a grid is meshed, so importing this package is cheap.
"""

from .bspline import BSplineSurface, HeightField, basis_functions, clamped_uniform_knots, dish, height_field
from .grids import QuadGrid, bspline_surface_grid, disk_grid, ellipse_grid, gmsh_session, rectangle_grid

__all__ = [
    "BSplineSurface",
    "HeightField",
    "QuadGrid",
    "basis_functions",
    "bspline_surface_grid",
    "clamped_uniform_knots",
    "dish",
    "disk_grid",
    "ellipse_grid",
    "gmsh_session",
    "height_field",
    "rectangle_grid",
]
