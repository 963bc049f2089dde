"""Gridshells built from rod networks: the pre-stressed hemisphere and its apex indentation."""

from .hemisphere import (
    PAPER,
    HemisphereModel,
    HemisphereSpec,
    PrestressResult,
    build_hemisphere,
    compare_shapes,
    prestress_by_paths,
    prestress_on_net,
)
from ..solvers.stability import count_negative, smallest_eigenpair
from .configurations import classify_configuration, configuration_features
from .indentation import (
    IndentationOptions,
    IndentationResult,
    IndentationSetup,
    Snap,
    indentation_system,
    trace_indentation,
)
from .study import IndentationCase, construction_case, indentation_case

__all__ = [
    "PAPER",
    "HemisphereModel",
    "HemisphereSpec",
    "PrestressResult",
    "build_hemisphere",
    "compare_shapes",
    "prestress_by_paths",
    "prestress_on_net",
    "IndentationOptions",
    "IndentationResult",
    "IndentationSetup",
    "Snap",
    "classify_configuration",
    "configuration_features",
    "count_negative",
    "indentation_system",
    "smallest_eigenpair",
    "trace_indentation",
    "IndentationCase",
    "construction_case",
    "indentation_case",
]
