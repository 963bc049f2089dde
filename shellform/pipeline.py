"""The scene runner under its earlier name: see :mod:`shellform.analyses`."""

from .analyses import ANALYSES, STAGES, run_continuation_case, run_scene

__all__ = ["ANALYSES", "STAGES", "run_continuation_case", "run_scene"]
