"""Second-order accuracy of the kinematic loop: each level's reference corrected for the curvature
of one tick.

The device holds ``v`` over a tick of ``dt`` seconds (:func:`sotdrake.configuration.integrate`), so
a task's error moves by

    ``e_{k+1} - e_k = J_k v_k dt + ½ (H v_k) v_k dt² + O(dt³)``     (``H = ∂J/∂q``)

and a solver that asks ``J_k v = ė*`` leaves the second-order term behind every tick. For a held
contact (``ė* = 0``) while the rest of the body moves fast in the contact's null space, it
accumulates into a drift that the contact's own gain balances only at ``‖e‖ ≈ ½‖(H v) v‖ dt / λ``
(TALOS reaching 3 m away at its velocity limits: 0.64 mm of foot drift with the tutorial's
λ = 10 /s). The last tick gives that term: the device moved by ``Δq = v_{k-1} dt`` and
``J_k - J_{k-1} ≈ (H v_{k-1}) dt``, so with ``y_{k-1} = J_{k-1} v_{k-1}`` (the level's velocity
as commanded at the last tick, kept in the solver's state)

    ``c_k dt = ½ (J_k - J_{k-1}) v_{k-1} = ½ (J_k v_{k-1} - y_{k-1}) ≈ ½ (H v_{k-1}) v_{k-1} dt``,

and the solver asks ``J_k v = ė* - c_k dt``, i.e. every bound of the level is shifted by ``-c_k dt``
(units of ``ė``). The term is quadratic in ``v``, so it stays right when ``v`` keeps its size, also
when a chattering solution flips its sign each tick (where extrapolating the Jacobian to mid-tick
would double the drift instead). The correction is skipped (zero) on the first tick of a level, when
its size changes, or when its Jacobian jumped rather than moved: ``‖(J_k - J_{k-1}) v‖ >
MAX_RELATIVE_CHANGE · ‖J_k‖ ‖v‖`` (Frobenius norm of ``J_k``: a new selection or frame).
"""

from __future__ import annotations

import numpy as np

from ..compiled import kernels

#: Largest relative change of a Jacobian over one tick that counts as motion.
MAX_RELATIVE_CHANGE = 0.1


def curvature_correction(J: np.ndarray, previous_velocity: np.ndarray | None,
                         previous_task_velocity: np.ndarray | None) -> np.ndarray | None:
    """``c_k dt = ½ (J_k v_{k-1} - y_{k-1})`` (units of ``ė``), or None (see the module docstring);
    ``previous_velocity`` is ``v_{k-1}``, ``previous_task_velocity`` is ``y_{k-1} = J_{k-1} v_{k-1}``.
    Computed by the compiled :func:`.jit_second_order.correction` (its numpy reference is the tests'
    oracle, ``tests/oracles.py``)."""
    if previous_velocity is None or previous_task_velocity is None or previous_task_velocity.shape != (J.shape[0],):
        return None
    if J.ndim != 2 or previous_velocity.shape != (J.shape[1],):
        raise ValueError(f"curvature correction: a {J.shape} Jacobian and a velocity of shape {previous_velocity.shape}")
    moved, correction = _jit_second_order().correction(J, previous_velocity, previous_task_velocity, MAX_RELATIVE_CHANGE)
    return correction if moved else None


_jit_second_order = kernels(".jit_second_order", __package__, "correction", "the tick-curvature correction", "a few seconds")
