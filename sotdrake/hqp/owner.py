"""What the stage paths (:mod:`.paths`), the rescues (:mod:`.rescue`) and the equality-stack path
(:mod:`.equality_stack`) read of the solver that runs them (:class:`.solve.HierarchicalQP`): its
size, tolerances and settings, the warm start of the call and its cached Drake programs."""

from __future__ import annotations

from typing import Protocol

from .drake_program import DrakePrograms
from .warm import WarmStart


class StageOwner(Protocol):
    n: int  # the number of variables
    rank_threshold: float  # singular values below it (relative) are taken as zero
    feasibility_tolerance: float  # a hard row holds within it
    hold_tolerance: float  # how much the levels below a held inequality row may pass it
    regularize: bool  # the minimum-norm stage runs after the levels
    level_solvers: list[str]  # the path chosen for each level (empty: the default)
    warm: WarmStart  # the warm start of the call being solved
    programs: DrakePrograms  # Drake's programs and solvers, cached
