"""Numpy references of compiled kernels that run only in the tests (the oracles they are compared
with on random inputs): a reference that does not run in production lives here, not in the package."""

import numpy as np

from sotdrake.solvers import second_order


def velocity_bounds(bounds, q: np.ndarray, dt: float, margin: float, control_selection: np.ndarray | None = None,
                    base_velocity: tuple[float, float] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``VelocityBounds(...)(q, …)`` (``bounds``) in numpy: the oracle of the compiled bounds."""
    outside_lower, outside_upper = bounds._outside_joints(base_velocity)
    lower, upper = outside_lower.copy(), outside_upper.copy()
    qj, lo, hi = q[bounds._iq], bounds._q_lower, bounds._q_upper
    # (Infinite position limits give ±inf here, never NaN: q and the margin are finite.)
    up = np.maximum((hi - margin - qj) / dt, np.minimum(0.0, (hi - qj) / dt))
    down = np.minimum((lo + margin - qj) / dt, np.maximum(0.0, (lo - qj) / dt))
    v_lo, v_hi = bounds._v_lower, bounds._v_upper
    up = np.minimum(np.maximum(up, v_lo), v_hi)  # np.clip, without its wrapper's cost
    down = np.minimum(np.maximum(down, v_lo), v_hi)
    upper[bounds._iv] = up
    lower[bounds._iv] = np.minimum(down, up)
    if control_selection is not None:
        unselected = ~control_selection
        lower[unselected] = upper[unselected] = 0.0
    return lower, upper


def curvature_correction(J: np.ndarray, previous_velocity: np.ndarray | None,
                         previous_task_velocity: np.ndarray | None) -> np.ndarray | None:
    """:func:`sotdrake.solvers.second_order.curvature_correction` in numpy: its oracle."""
    if previous_velocity is None or previous_task_velocity is None or previous_task_velocity.shape != (J.shape[0],):
        return None
    change = J @ previous_velocity - previous_task_velocity
    flat = J.reshape(-1)
    scale = second_order.MAX_RELATIVE_CHANGE**2 * flat.dot(flat) * previous_velocity.dot(previous_velocity)
    if change.dot(change) > scale:
        return None
    return 0.5 * change
