"""The hierarchical QP: pure solver code, no Drake system in it.

``problem`` (the level rows, the answer, a built stage), ``solve`` (:class:`HierarchicalQP`:
checks, then per stage build / try the paths / accept), ``paths`` (the ordered list of the paths a
stage tries, declared once, and the shortcuts that need no stage), ``stack_paths`` (the ways a
whole stack is solved at once, the cascade and the QR sweep among them, and which solver tries
which, in order; ``stack_problem``: the stack they take, checked once), ``equality_stack`` (a whole
equality stack at once from the held bounds, before any stage), ``tolerances`` (every tolerance
of the wing, defined once), the algorithms (``active_set`` and its multipliers' sign test ``multipliers``,
``active_bounds``, ``equality_hierarchy``, ``cascade``), Drake's
``MathematicalProgram`` path (``drake_program``), the rescue paths (``rescue``), the warm-start
state that systems keep in their Context (``warm``), and the compiled kernels (``kernels``).
"""

from .cascade import CascadeResult, solve_cascade
from .solve import ACTIVE_BOUNDS, ACTIVE_SET, SOLVERS, HierarchicalQP, HqpResult, LevelRows, check_solver
from .stack_paths import BASIC, DYNAMIC, KINEMATIC, StackPath, StackProblem, solve_stack
from .warm import WarmStart

__all__ = ["ACTIVE_BOUNDS", "ACTIVE_SET", "BASIC", "DYNAMIC", "KINEMATIC", "SOLVERS", "CascadeResult", "HierarchicalQP",
           "HqpResult", "LevelRows", "StackPath", "StackProblem", "WarmStart", "check_solver", "solve_cascade", "solve_stack"]
