"""The solver systems of the kinematic stack (``SOT``, ``SolverKine``) and the settings they share.
Their maths is :mod:`sotdrake.hqp` (whose names stay importable from here)."""

from ..hqp import HierarchicalQP, HqpResult, LevelRows  # noqa: F401  (documented in sotdrake.hqp)
from ..hqp.cascade import CascadeResult, solve_cascade  # noqa: F401  (documented in sotdrake.hqp)
from .solver_kine import HqpDiagnostics, SolverKine
from .sot import SOT, StackSettings

__all__ = ["SOT", "HqpDiagnostics", "SolverKine", "StackSettings"]
