"""Solvers of the stack: the maths as pure functions, and the ``LeafSystem``s around them."""

from ..hqp import HierarchicalQP, HqpResult, LevelRows
from .cascade import CascadeResult, solve_cascade
from .solver_kine import HqpDiagnostics, SolverKine
from .sot import SOT, StackSettings

__all__ = [
    "SOT",
    "CascadeResult",
    "HierarchicalQP",
    "HqpDiagnostics",
    "HqpResult",
    "LevelRows",
    "SolverKine",
    "StackSettings",
    "solve_cascade",
]
