"""The step limit: how far one tick may move each coordinate, so that the linearised tasks hold.

A kinematic solver asks ``J v = ė*`` of each level with the Jacobian at the tick's start; the
device then holds ``v`` for the whole period ``dt``. A task's error moves by

    ``e_{k+1} − e_k = J v dt + ½ (H v) v dt² + O(dt³)``

and the curvature correction (:mod:`.second_order`) removes the second-order term only as far as
the last tick's ``v`` predicts this one's. What it leaves grows with the step ``v dt`` squared: a
held contact drifts by about ``‖v dt‖²`` times the lever arm of the moving joints. So the solvers
bound each component of the command by

    ``|v_i| ≤ δ / dt``        (δ: the step limit, rad or m per tick, default 7e-3)

TALOS' fastest joints are limited to 7 rad/s: at ``dt`` = 1 ms the step limit is their velocity
limit and changes nothing; at 5 ms it caps every joint at 1.4 rad/s, at 10 ms at 0.7 rad/s. On
randomized hostile stacks (far targets, gains up to ``λ·dt`` = 1.9, joints starting on their limits)
it keeps both feet within 0.1 mm at every period (``bench/hostile.py``), where without it the feet
of a 5 ms run slide by up to 0.6 mm. ``SOT`` scales its whole command into the bound (as into the
velocity limits, :mod:`.velocity_scaling`); ``SolverKine`` adds it to its velocity bounds.
``setStepLimit(inf)`` removes it.
"""

from __future__ import annotations

import math

import numpy as np

from ..exceptions import InvalidInput

#: The default step limit δ (rad or m per tick).
DEFAULT_STEP_LIMIT = 7e-3
#: The largest finite step limit accepted (rad or m per tick); ``inf`` means none.
MAX_STEP_LIMIT = 1.0


def check_step_limit(name: str, step: object) -> float:
    """``step`` as a float in ``(0, MAX_STEP_LIMIT]`` or ``inf``, else :class:`InvalidInput`."""
    if isinstance(step, bool) or not isinstance(step, (int, float, np.integer, np.floating)) or not (
            step == math.inf or 0 < step <= MAX_STEP_LIMIT):
        raise InvalidInput(f"{name}.setStepLimit: the step limit must be a number in (0, {MAX_STEP_LIMIT:g}] "
                           f"(rad or m per tick) or inf (none), got {step!r:.50}")
    return float(step)


def clip_bounds(lower: np.ndarray, upper: np.ndarray, cap: float | np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``lower ≤ v ≤ upper`` intersected with ``|v| ≤ cap``; a bound beyond the cap (a joint
    outside its position limits, asked to come back faster) is brought to it, so the bounds stay
    ordered."""
    return np.clip(lower, -cap, cap), np.clip(upper, -cap, cap)
