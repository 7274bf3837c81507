"""Solvers of the stack: the maths as pure functions, and the ``LeafSystem``s around them."""

from .cascade import CascadeResult, solve_cascade
from .sot import SOT, StackSettings

__all__ = ["SOT", "CascadeResult", "StackSettings", "solve_cascade"]
