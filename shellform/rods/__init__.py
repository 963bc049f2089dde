"""Discrete elastic rods: sections, networks, boundary conditions and load stepping.

The kinematics and energies of a rod are effects (:mod:`shellform.effects.rod_kinematics`,
:mod:`shellform.effects.rod_hinge` and the ``rod_*`` energies).
"""

from ..effects.rod_kinematics import ReferenceFrames
from .grids import square_grid_polylines
from .network import Rod, RodNetwork, build_rod_system
from .node_path import NodePath
from .polylines import resample_polyline, stack_polylines
from .section import RestShape, RodSection, circular_section
from .statics import IncrementalOptions, IncrementalResult, SupportsAt, accept_state, solve_incremental

__all__ = [
    "ReferenceFrames",
    "NodePath",
    "RestShape",
    "Rod",
    "RodNetwork",
    "RodSection",
    "build_rod_system",
    "circular_section",
    "resample_polyline",
    "stack_polylines",
    "square_grid_polylines",
    "IncrementalOptions",
    "IncrementalResult",
    "SupportsAt",
    "accept_state",
    "solve_incremental",
]
