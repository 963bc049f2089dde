"""Solvers: static Newton, linear algebra (and, in their own modules, continuation and dynamics)."""

from .linear import SingularMatrixError, factorize
from .newton import StaticResult, solve_static

__all__ = ["SingularMatrixError", "factorize", "StaticResult", "solve_static"]
