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

A level whose rows come and go (the collision pairs in range: ``TaskLevel.row_keys``) is corrected
row by row: row ``i`` gets ``½ (J_k,i v_{k-1} − y_{k-1,j})`` from the row ``j`` of the last tick that
had its key, when its own Jacobian moved rather than jumped (``|J_k,i v − y_j| ≤
MAX_RELATIVE_CHANGE ‖J_k,i‖ ‖v‖``: a witness point that switched features jumps), else 0. Rows
matched by their place instead would shift one pair's bound by another pair's correction.

An equality row's reference is shifted by the correction (both ways); an inequality's bound is
only ever tightened by it (:func:`corrected_bounds`). The correction is the last tick's velocity's
curvature; when the command brakes at a bound (an arm stopping short of the table), the new
velocity's is smaller, and a bound loosened by the old one lets the row cross it (a gripper 0.9 mm
into the table at a 10 ms tick). Left as it is, a bound the motion curves away from is kept with a
margin of at most that correction.
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


def keyed_curvature_correction(J: np.ndarray, keys: np.ndarray, previous_velocity: np.ndarray | None,
                               previous: tuple[np.ndarray, np.ndarray] | None) -> np.ndarray | None:
    """Row by row ``c_k dt`` of a level whose rows are told apart by ``keys`` (one integer per row of
    ``J``), ``previous = (y_{k-1}, its rows' keys)`` (see the module docstring); None before the
    level's first tick."""
    if previous_velocity is None or previous is None:
        return None
    y, previous_keys = previous
    if J.ndim != 2 or previous_velocity.shape != (J.shape[1],) or np.shape(keys) != (J.shape[0],):
        raise ValueError(f"curvature correction: a {J.shape} Jacobian, {np.shape(keys)} keys and a velocity of shape "
                         f"{previous_velocity.shape}")
    correction = np.zeros(J.shape[0])
    if not len(y) or not J.shape[0]:
        return correction
    order = np.argsort(previous_keys, kind="stable")
    place = np.minimum(np.searchsorted(previous_keys[order], keys), len(order) - 1)
    found = previous_keys[order][place] == keys
    change = J @ previous_velocity - y[order[place]]
    moved = np.abs(change) <= MAX_RELATIVE_CHANGE * np.linalg.norm(J, axis=1) * np.linalg.norm(previous_velocity)
    matched = found & moved
    correction[matched] = 0.5 * change[matched]
    return correction


def corrected_bounds(lower: np.ndarray, upper: np.ndarray, correction: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The bounds of a level with its correction (see the module docstring): an equality row's
    (``lower == upper``) both shifted by ``-correction``, an inequality's only tightened."""
    if upper is lower:
        shifted = lower - correction
        return shifted, shifted
    equal = lower == upper
    return (np.where(equal, lower - correction, lower - np.minimum(correction, 0.0)),
            np.where(equal, upper - correction, upper - np.maximum(correction, 0.0)))

