"""The hierarchical QP: pure solver code, no Drake system in it.

``solve`` (:class:`HierarchicalQP`, the stage loop), ``paths`` (the ordered list of the paths a
stage tries, declared once), ``tolerances`` (every tolerance of the wing, defined once), the
algorithms (``active_set``, ``active_bounds``, ``equality_hierarchy``), Drake's
``MathematicalProgram`` path (``drake_program``), the rescue paths (``rescue``), the warm-start
state that systems keep in their Context (``warm``), and the compiled kernels (``kernels``).
"""

from .solve import ACTIVE_BOUNDS, ACTIVE_SET, SOLVERS, HierarchicalQP, HqpResult, LevelRows, check_solver

__all__ = ["ACTIVE_BOUNDS", "ACTIVE_SET", "SOLVERS", "HierarchicalQP", "HqpResult", "LevelRows", "check_solver"]
