"""Every tolerance of the hierarchical QP, defined once.

Rows are compared at unit norm; "relative above 1" means a tolerance ``t`` on a value ``v`` reads
``t · max(1, |v|)``. The compiled kernels read these numbers as constants when numba compiles them:
numba's cache on disk is keyed by each kernel's own file, so after changing a number here, delete
the ``__pycache__`` folders of :mod:`sotdrake.hqp` (or touch the kernels' files) to recompile.
"""

from __future__ import annotations

RANK_THRESHOLD = 1e-8
"""Default τ: singular values ≤ τ of unit-row matrices count as zero (the rank of every level)."""

CERTIFIED_FACTOR = 1e3
CERTIFIED = CERTIFIED_FACTOR * RANK_THRESHOLD
"""The smallest singular value of a level's unit rows, in what is left free, that counts as clearly
non-zero (10³ τ): below it, the QR paths (:mod:`.equality_hierarchy`, :mod:`.active_bounds`) leave
the decision to the active set. With another τ, ``CERTIFIED_FACTOR · τ``."""

NEGLIGIBLE = 1e-3 * RANK_THRESHOLD
"""The largest singular value that counts as clearly zero (round-off of a row the levels above fix)."""

FEASIBILITY = 1e-9
"""The bound violation (on unit rows, relative above 1) beyond which a path's point is refused and
the next path tried (:class:`~.solve.HierarchicalQP`'s default ``feasibility_tolerance``); also the
margin by which a component counts as in the way of a bound (:data:`.equality_hierarchy.IN_THE_WAY`)
and the margin of the last answer's held bounds read as the next call's guess."""

VERIFIED = 1e-10
"""The stricter bound check of the compiled paths (the active bounds, an equality level's
least-squares step, the active set's own verification): a point they certify is inside its bounds
to this (relative above 1)."""

MULTIPLIER_TOLERANCE = 1e-9
"""A held bound's (or row's) multiplier may have the wrong sign by this much, relative to the size
of the residual (``max(1, ‖x‖)`` in :mod:`.active_bounds`, ``‖ρ‖ ‖c‖`` in :mod:`.equality_hierarchy`,
``max(m_scale) · max(‖M z − t‖, MULTIPLIER_FLOOR (max(m_scale) ‖z‖ + ‖t‖))`` in :mod:`.active_set`, and
below that each multiplier's own round-off from each objective row's residual, :mod:`.multipliers`)."""

MULTIPLIER_FLOOR = 1e-6
"""In :mod:`.active_set`, the residual below which the multipliers' tolerance stops shrinking, as a
fraction of the size of the level's terms (``max(m_scale) ‖z‖ + ‖t‖``): a level met exactly still
has round-off in its multipliers. Relative to the data, not absolute: a level whose optimum is
decided by rows of norm 1e-6 (a nearly flat level) has multipliers of about 1e-10 that must keep
their sign."""

RATIO_TIE = 1e-12
"""Two ratios of the active set's ratio test within this factor of each other are a tie, broken by
the smallest index (Bland's rule)."""

NO_STEP = 1e-12
"""A step of the active set that moves ``z`` by at most this (relative above 1) is no step: the row
just dropped blocking at once means its multiplier's sign was round-off."""

ROUND_OFF = 1e-9
"""A hard row missed by at most this fraction of the point's size is missed by round-off (the
rescue :func:`.rescue.onto_hard_rows` moves the point onto it)."""

HELD_SIDE = 1e-12
"""An inequality row is recorded as held at a side (for the next levels' guess) within this,
relative above 1."""

SIDE = 1e-6
"""A Drake solver's point holds a row at a side within this, relative above 1 (its working set)."""

REPORTED_ACTIVE = 1e-7
"""A row or bound is reported active (:class:`~.solve.HqpResult`) within this of a side, relative above 1."""

DEGENERATE_RETRY = (1e-4, 1e-3)
"""At a degenerate vertex, where bounds or held rows meet nearly dependent at the same value, the
working set's rank decisions at τ can leave out a row that the held ones imply only to within τ:
it then moves off its bound by up to about τ times the step (seen on ``SolverDyn``'s last level at
random valid states: 2e-8 on a unit row, against the 1e-9 every point must meet; about 4 random
states in 100 failed so), or the working sets cycle (the dropped row, pushed off, blocks the next
step at once). A stage whose active-set paths end outside the bounds or cycle is solved once more
by the active set (cold guess) with the working set's rank decisions at these fractions of τ in turn,
right after the active set's own paths and before the Drake solvers' (which cost about 140 ms each
on such a stage, and end outside the bounds too); every other rank decision stays at τ, and the
point is accepted on the same checks (see :mod:`.paths`)."""
