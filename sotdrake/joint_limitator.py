"""The ``JointLimitator`` entity (sot-core): a filter between the solver and the device that stops a
joint whose next position would leave its limits.

The rule, per joint coordinate ``i`` (rad or m), with the look-ahead step ``h`` (s)::

    v_out_i = v_i   if  q_lower_i < q_i + h·v_i < q_upper_i
    v_out_i = 0     otherwise

The inequalities are strict, as in sot-core: a joint on its limit keeps a velocity that takes it
away from the limit and gets exactly zero toward it (or of zero). The floating base's velocities
pass unchanged (sot-core: "do not take into account the free flyer"). The rule reads the next
position only: a joint already outside its limits keeps a velocity that brings it back inside
within the step ``h``, and any slower return is zeroed (sot-core's rule; no solver in sotdrake puts
a joint there).

sot-core hard-codes ``h = 0.005`` s (the period of the robots it was written for); here ``h`` is a
setting, by default the device's period. The filter changes the command only, never the stack's
priorities: a zeroed joint is not compensated by the others (the hand may then miss its target where
the hierarchical QP, which holds the limits as constraints, would reach it with other joints).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.framework import BasicVector, Context

from .configuration import Layout
from .entity import Entity
from .exceptions import InvalidInput, SolverError, all_numbers, check_finite, finite_number

__all__ = ["JointLimitator", "limit_joint_velocities"]

#: The longest look-ahead step accepted (s).
MAX_STEP = 10.0


def limit_joint_velocities(q: np.ndarray, v: np.ndarray, lower: np.ndarray, upper: np.ndarray, step: float) -> np.ndarray:
    """sot-core's ``JointLimitator`` rule on joint coordinates: ``v_i`` where ``lower_i < q_i +
    step·v_i < upper_i``, 0 elsewhere (a new array).

    ``q`` (rad or m), ``v`` (rad/s or m/s), ``lower`` and ``upper`` (rad or m, ``±inf`` for none) have
    one entry per joint coordinate; ``step`` (s) is the look-ahead. Checked (:class:`InvalidInput`
    naming the argument): ``q`` and ``v`` finite, of one size n, ``lower`` and ``upper`` n numbers
    without NaN with ``lower ≤ upper``, ``lower < +inf``, ``upper > -inf`` (as :meth:`JointLimitator.setLimits`),
    ``step`` in ``(0, MAX_STEP]`` (as :meth:`JointLimitator.setStep`): a NaN position or crossed
    limits used to zero every velocity silently."""
    q = check_finite("limit_joint_velocities: q", q)
    if q.ndim != 1:
        raise InvalidInput(f"limit_joint_velocities: q must be one position per joint coordinate (a vector), got shape {q.shape}")
    v = check_finite("limit_joint_velocities: v", v, q.shape)
    lower, upper = (_limit_array(f"limit_joint_velocities: {name}", value, name, q.shape)
                    for name, value in (("lower", lower), ("upper", upper)))
    if np.any(lower > upper):
        i = int(np.flatnonzero(lower > upper)[0])
        raise InvalidInput(f"limit_joint_velocities: lower must be ≤ upper; joint coordinate {i}: {lower[i]:g} > {upper[i]:g}")
    if not (finite_number(step) and 0 < step <= MAX_STEP):
        raise InvalidInput(f"limit_joint_velocities: step must be a number in (0, {MAX_STEP:g}] s, got {step!r:.60}")
    return _limit_joint_velocities(q, v, lower, upper, float(step))


def _limit_joint_velocities(q: np.ndarray, v: np.ndarray, lower: np.ndarray, upper: np.ndarray, step: float) -> np.ndarray:
    """:func:`limit_joint_velocities` without its checks (the entity's every tick: its settings are checked when set)."""
    q_next = q + step * v
    return np.where((q_next > lower) & (q_next < upper), v, 0.0)


def _limit_array(what: str, value, name: str, shape: tuple[int, ...]) -> np.ndarray:
    """``value`` as a float array of ``shape`` (a copy), limits of the side ``name`` ('lower' or
    'upper'): no NaN, not the infinity of the other side; else :class:`InvalidInput` naming ``what``."""
    try:
        if not all_numbers(value):
            raise TypeError("not numbers")
        array = np.array(value, dtype=float)  # (a copy: the caller's array may change later)
    except (TypeError, ValueError):
        raise InvalidInput(f"{what} must be {shape[0]} numbers (rad or m), got {value!r:.200}") from None
    if array.shape != shape:
        raise InvalidInput(f"{what} must be {shape[0]} numbers (one per joint coordinate), got shape {array.shape}")
    if np.any(np.isnan(array)):
        raise InvalidInput(f"{what} contains NaN: {array}")
    wrong_side = np.inf if name == "lower" else -np.inf  # (no position is below +inf or above -inf)
    if np.any(array == wrong_side):
        raise InvalidInput(f"{what} must not be {wrong_side:g} (it would stop the joint for good); ±inf on its own side is no limit")
    return array  # -inf lower, +inf upper: no limit


@dataclass
class LimitatorSettings:
    step: float
    lower: np.ndarray  # one per joint coordinate (the Layout's joints_q), -inf for none
    upper: np.ndarray


class JointLimitator(Entity[LimitatorSettings]):
    """sot-core's ``JointLimitator``: the solver's command with the joints that would leave their
    limits stopped (:func:`limit_joint_velocities`); plugged ``solver.control → control_in``,
    ``control → device.control``.

    Inputs: ``position`` (nq, Drake positions: the device's ``state``), ``control_in`` (nv, Drake
    generalized velocities: rad/s, m/s). Output: ``control`` (nv), the floating base's part unchanged.

    Settings (in the Context): the look-ahead ``step`` (s, default ``dt``) and the joints' limits
    (default the plant's position limits), changed by :meth:`setStep` and :meth:`setLimits`."""

    def __init__(self, plant: MultibodyPlant, dt: float, name: str = "joint_limitator"):
        if not (finite_number(dt) and 0 < dt <= MAX_STEP):
            raise InvalidInput(f"{name}: dt (the look-ahead step) must be a number in (0, {MAX_STEP:g}] s, got {dt!r}")
        self.layout = Layout.of(plant)
        joints = self.layout.joints_q
        lower = plant.GetPositionLowerLimits()[joints]
        upper = plant.GetPositionUpperLimits()[joints]
        Entity.__init__(self, name, LimitatorSettings(float(dt), lower, upper))
        nq, nv = self.layout.nq, self.layout.nv
        self._position = self.DeclareVectorInputPort("position", nq)
        self._control_in = self.DeclareVectorInputPort("control_in", nv)
        self.DeclareVectorOutputPort("control", nv, self._calc)

    def _calc(self, context: Context, output: BasicVector) -> None:
        v = self._control_in.Eval(context)
        if not math.isfinite(v.sum()):
            raise SolverError(f"{self.name}: non-finite control_in at t = {context.get_time()}: {v}")
        s = self._settings_of(context)
        q = self._position.Eval(context)
        out = v.copy()
        joints_v = self.layout.joints_v
        out[joints_v] = _limit_joint_velocities(q[self.layout.joints_q], v[joints_v], s.lower, s.upper, s.step)
        output.SetFromVector(out)

    def setStep(self, step: float, context: Context | None = None) -> None:
        """The look-ahead step ``h`` (s) of the rule ``q + h·v`` (sot-core: 0.005)."""
        if not (finite_number(step) and 0 < step <= MAX_STEP):
            raise InvalidInput(f"{self.name}.setStep: step must be a number in (0, {MAX_STEP:g}] s, got {step!r}")
        self._command(context, lambda s: setattr(s, "step", float(step)))

    def setLimits(self, lower, upper, context: Context | None = None) -> None:
        """The joints' position limits (rad or m), one per joint coordinate (``joint_count``),
        ``lower ≤ upper``; ``±inf`` for none (sot-core's ``lowerJl`` and ``upperJl`` inputs)."""
        n = len(self.layout.joints_q)
        lo = self._limit("lower", lower, n)
        hi = self._limit("upper", upper, n)
        if np.any(lo > hi):
            i = int(np.flatnonzero(lo > hi)[0])
            raise InvalidInput(f"{self.name}.setLimits: lower must be ≤ upper; joint coordinate {i}: {lo[i]:g} > {hi[i]:g}")

        def change(s: LimitatorSettings) -> None:
            s.lower, s.upper = lo, hi

        self._command(context, change)

    def _limit(self, name: str, value, n: int) -> np.ndarray:
        return _limit_array(f"{self.name}.setLimits: {name}", value, name, (n,))

    @property
    def joint_count(self) -> int:
        """The number of joint coordinates (nq without the floating base's 7)."""
        return len(self.layout.joints_q)

    def limits(self, context: Context | None = None) -> tuple[np.ndarray, np.ndarray]:
        """The joints' lower and upper limits in ``context`` (or the defaults)."""
        s = self.settings(context)
        return s.lower.copy(), s.upper.copy()
