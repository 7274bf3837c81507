"""Joint limits as velocity bounds over one tick: the hard constraints above every task.

For a joint with position limits ``[q_min, q_max]``, velocity limits ``[v_min, v_max]``, tick
``dt`` and margin ``m`` (rad or m), the upper bound on its velocity is

* ``(q_max - m - q)/dt`` while the joint is farther than ``m`` from its limit;
* ``0`` inside the margin (it may stay, it is not pushed out: a start on the boundary is fine);
* ``(q_max - q)/dt < 0`` if it is beyond the limit (brought back in one tick),

then capped by ``v_max``; the lower bound is symmetric. Where the two would cross (a violated limit
faster than the velocity limit allows to fix), the position side wins within the velocity limit.
The floating base's velocity is bounded only when ``base_velocity = (ω̄, v̄)`` is given: each
component of its angular velocity in ``[-ω̄, ω̄]`` (rad/s), of its linear velocity in ``[-v̄, v̄]``
(m/s) (default of the solvers: :mod:`.base_velocity`). Coordinates excluded by a control selection
get ``[0, 0]``.
"""

from __future__ import annotations

import numpy as np

from ..compiled import compiled_input, kernels
from ..configuration import Layout


def velocity_bounds(
    q: np.ndarray,
    position_lower: np.ndarray,
    position_upper: np.ndarray,
    velocity_lower: np.ndarray,
    velocity_upper: np.ndarray,
    dt: float,
    margin: float,
    layout: Layout,
    control_selection: np.ndarray | None = None,
    base_velocity: tuple[float, float] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """``(lower, upper)`` bounds on ``v`` (size nv); see the module docstring."""
    bounds = VelocityBounds(position_lower, position_upper, velocity_lower, velocity_upper, layout)
    return bounds(q, dt, margin, control_selection, base_velocity)


class VelocityBounds:
    """:func:`velocity_bounds` of one robot: its limits read at the joints' coordinates once (a
    solver calls it every tick with the same limits)."""

    def __init__(self, position_lower: np.ndarray, position_upper: np.ndarray, velocity_lower: np.ndarray,
                 velocity_upper: np.ndarray, layout: Layout):
        iq = layout.joints_q_slice if layout.joints_q_slice is not None else layout.joints_q
        iv = layout.joints_v_slice if layout.joints_v_slice is not None else layout.joints_v
        self._iq, self._iv, self._layout = iq, iv, layout
        self._q_lower, self._q_upper = np.array(position_lower[iq], dtype=float), np.array(position_upper[iq], dtype=float)
        self._v_lower, self._v_upper = np.array(velocity_lower[iv], dtype=float), np.array(velocity_upper[iv], dtype=float)
        self._nv = len(velocity_lower)
        self._unbounded: dict[tuple[float, float] | None, tuple[np.ndarray, np.ndarray]] = {}  # a cache of constants
        # The compiled bounds' arguments (the joints' coordinates as indices, C-ordered limits).
        self._joints_q = np.ascontiguousarray(layout.joints_q, dtype=np.int64)
        self._joints_v = np.ascontiguousarray(layout.joints_v, dtype=np.int64)
        self._limits = tuple(compiled_input(a) for a in (self._q_lower, self._q_upper, self._v_lower, self._v_upper))
        self._all_selected = np.zeros(0, dtype=np.bool_)
        self._nq = layout.nq

    def _outside_joints(self, base_velocity: tuple[float, float] | None) -> tuple[np.ndarray, np.ndarray]:
        """The bounds of the components that are not joints (±∞, or the base's), made once per value."""
        pair = self._unbounded.get(base_velocity)
        if pair is None:
            lower, upper = np.full(self._nv, -np.inf), np.full(self._nv, np.inf)
            b = self._layout.base_v
            if base_velocity is not None and b is not None:
                angular, linear = base_velocity
                lower[b : b + 3], upper[b : b + 3] = -angular, angular
                lower[b + 3 : b + 6], upper[b + 3 : b + 6] = -linear, linear
            lower.flags.writeable = upper.flags.writeable = False
            pair = self._unbounded[base_velocity] = (lower, upper)
        return pair

    def __call__(self, q: np.ndarray, dt: float, margin: float, control_selection: np.ndarray | None = None,
                 base_velocity: tuple[float, float] | None = None) -> tuple[np.ndarray, np.ndarray]:
        """``(lower, upper)`` bounds on ``v`` at the configuration ``q``; see the module docstring.
        Compiled (:mod:`.jit_limits`); its numpy reference is the tests' oracle (``tests/oracles.py``)."""
        outside_lower, outside_upper = self._outside_joints(base_velocity)
        q = compiled_input(q)
        if q.shape != (self._nq,):  # (the compiled code reads the joints' entries unchecked)
            raise ValueError(f"q: expected {self._nq} positions, got shape {q.shape}")
        unselected = self._all_selected if control_selection is None else ~compiled_input(control_selection, np.bool_)
        if unselected.shape not in ((0,), (self._nv,)):
            raise ValueError(f"control selection: expected {self._nv} booleans, got shape {unselected.shape}")
        return _jit_limits().bounds(q, self._joints_q, self._joints_v, *self._limits, outside_lower, outside_upper,
                                    float(dt), float(margin), unselected)



_jit_limits = kernels(".jit_limits", __package__, "bounds", "the joint limits' velocity bounds", "a few seconds")
