"""Discrete elastic rods: kinematics, hinge derivatives, networks and boundary conditions."""

from .kinematics import ReferenceFrames
from .network import (
    NodePath,
    Rod,
    RodNetwork,
    build_rod_system,
    circular_section,
    resample_polyline,
    stack_polylines,
)

__all__ = [
    "ReferenceFrames",
    "NodePath",
    "Rod",
    "RodNetwork",
    "build_rod_system",
    "circular_section",
    "resample_polyline",
    "stack_polylines",
]
