"""Second-order accuracy of the kinematic loop: each level's reference corrected for the curvature
of one tick.

The device holds ``v`` over a tick of ``dt`` seconds (:func:`sotdrake.device.integrate`), so a
task's error moves by

    ``e_{k+1} - e_k = J_k v_k dt + ½ (H v_k) v_k dt² + O(dt³)``     (``H = ∂J/∂q``)

and a solver that asks ``J_k v = ė*`` leaves the second-order term behind every tick. For a held
contact (``ė* = 0``) while the rest of the body moves fast in the contact's null space, it
accumulates into a drift that the contact's own gain balances only at ``‖e‖ ≈ ½‖(H v) v‖ dt / λ``
(TALOS reaching 3 m away at its velocity limits: 0.64 mm of foot drift with the tutorial's
λ = 10 /s). The last tick gives that term: with ``Δq = q_k ⊖ q_{k-1} = v_{k-1} dt``
(:func:`sotdrake.device.difference`) and ``J_k - J_{k-1} ≈ (H v_{k-1}) dt``,

    ``c_k = ½ (J_k - J_{k-1}) Δq / dt² ≈ ½ (H v_{k-1}) v_{k-1}``,

and the solver asks ``J_k v = ė* - c_k dt``, i.e. every bound of the level is shifted by ``-c_k dt``
(units of ``ė``). The term is quadratic in ``v``, so it stays right when ``v`` keeps its size, also
when a chattering solution flips its sign each tick (where extrapolating the Jacobian to mid-tick
would double the drift instead). The correction is skipped (zero) on the first tick of a level, when
its size changes, or when its Jacobian jumped (``‖J_k - J_{k-1}‖ > MAX_RELATIVE_CHANGE · ‖J_k‖``,
Frobenius norms: a new selection or frame, not a motion).
"""

from __future__ import annotations

import numpy as np

#: Largest relative change of a Jacobian over one tick that counts as motion.
MAX_RELATIVE_CHANGE = 0.1


def curvature_correction(J: np.ndarray, J_previous: np.ndarray | None, displacement: np.ndarray | None,
                         dt: float) -> np.ndarray | None:
    """``c_k dt = ½ (J_k - J_{k-1}) Δq / dt`` (units of ``ė``), or None (see the module docstring)."""
    if J_previous is None or displacement is None or J_previous.shape != J.shape or J.size == 0:
        return None
    change = J - J_previous
    if np.sum(change * change) > MAX_RELATIVE_CHANGE**2 * np.sum(J * J):
        return None
    return (0.5 / dt) * (change @ displacement)
