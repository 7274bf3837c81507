"""The hierarchical QP: pure solver code, no Drake system in it.

``problem`` (the level rows, the answer, a built stage), ``solve`` (:class:`HierarchicalQP`:
checks, then per stage build / try the paths / accept), ``paths`` (the ordered list of the paths a
stage tries, declared once, and the shortcuts that need no stage), ``equality_stack`` (a whole
equality stack at once from the held bounds, before any stage), ``tolerances`` (every tolerance
of the wing, defined once), the algorithms (``active_set``, ``active_bounds``, ``equality_hierarchy``), Drake's
``MathematicalProgram`` path (``drake_program``), the rescue paths (``rescue``), the warm-start
state that systems keep in their Context (``warm``), and the compiled kernels (``kernels``).
"""

from .solve import ACTIVE_BOUNDS, ACTIVE_SET, SOLVERS, HierarchicalQP, HqpResult, LevelRows, check_solver
from .warm import WarmStart

__all__ = ["ACTIVE_BOUNDS", "ACTIVE_SET", "SOLVERS", "HierarchicalQP", "HqpResult", "LevelRows", "WarmStart", "check_solver"]
