"""The accepted ranges of the dynamic SoT's settings, and the checks its commands and constructors run.

Every check raises :class:`~sotdrake.exceptions.InvalidInput` naming the argument and its accepted
range *before* anything changes (a command then leaves the Context's settings as they were). A
value must be a real number (not a bool, a string, a sequence or ``None``) inside its range; the
upper ends are far above any sensible value and only keep out the absurd (``1e300``), which would
otherwise reach the solver as infinite or overflowing rows.
"""

from __future__ import annotations

import numpy as np

from ..exceptions import InvalidInput, check_number
from ..task import unconnected_port

MAX_FRICTION = 10.0  # μ of a contact (dimensionless): rubber on concrete is about 1
MAX_NORMAL_FORCE = 1e4  # N: f_min of a contact (TALOS weighs 886 N)
MAX_RATE_GAIN = 1e3  # 1/s: a contact's K_v, the solver's K_d (the tick is 1 ms: K dt ≤ 1)
MAX_HORIZON = 10.0  # s: the joint limits' horizon
MIN_HORIZON = 1e-6  # s: its shortest (the bounds divide by its square)
MAX_POSITION_MARGIN = 0.1  # rad (m for a prismatic joint): the joint limits' margin
MAX_RELEASE = 60.0  # s: the ramp of rmContact
MAX_PD_GAIN = 1e8  # 1/s² for K_p, 1/s for K_v of TaskDynPD (the tick bounds them further: check_pd_gains)
MAX_DT = 1.0  # s: a control period
MAX_SOLE = 1.0  # m: |x|, |y| of a contact rectangle's edges
MAX_CONTACTS = 16
#: A contact's velocity gain ``K_v`` (1/s) by default, capped at ``COMPLIANT_CONTACT_RATE / dt``.
CONTACT_VELOCITY_GAIN = 30.0
#: The largest ``K_v dt`` of a contact's velocity damping measured stable on the physics plant's
#: compliant soles. The contact row ``J_C q̈ = −J̇_C v − K_v J_C v`` assumes a rigid contact, on which
#: ``v_C ← (1 − K_v dt) v_C`` is stable up to ``K_v dt < 2``; on the physics plant the sole velocity
#: fed back is the stiff sole-on-ground mode, and TALOS standing (SAP, hydroelastic soles) goes
#: unstable from ``K_v dt`` 0.2 to 0.4: K_v = 200 falls at a 1 ms tick, 60 at 5 ms, 30 at 10 ms
#: (150, 30 and 25 stand), the load jumping from one sole to the other at every tick.
COMPLIANT_CONTACT_RATE = 0.15


def default_contact_velocity_gain(dt: float | None) -> float:
    """A contact's default ``K_v`` (1/s): :data:`CONTACT_VELOCITY_GAIN`, at most
    ``COMPLIANT_CONTACT_RATE / dt`` (30 down to a 5 ms tick, 15 at 10 ms)."""
    return CONTACT_VELOCITY_GAIN if dt is None else min(CONTACT_VELOCITY_GAIN, COMPLIANT_CONTACT_RATE / dt)


def check_positive(name: str, value, high: float, unit: str = "") -> float:
    """``value`` as a float if it is a real number in ``(0, high]``, else :class:`InvalidInput`."""
    try:
        number = check_number(name, value, 0.0, high, unit)
    except InvalidInput:
        number = 0.0  # refused below, with the open range in the message
    if not number > 0.0:
        raise InvalidInput(f"{name} must be a number in (0, {high:g}]{unit}, got {value!r:.100}")
    return number


def check_pd_gains(name: str, kp, kv, dt: float) -> tuple[float, float]:
    """``(K_p, K_v)`` of :class:`.task_dyn_pd.TaskDynPD` as floats, each in ``[0, MAX_PD_GAIN]``,
    and a loop that the control tick ``dt`` keeps stable: the error ``ë = −K_p e − K_v ė``
    integrated by the device's semi-implicit Euler step (``ė ← ė + ë dt``, ``e ← e + ė dt``) has
    the characteristic polynomial ``z² − (2 − K_v dt − K_p dt²) z + 1 − K_v dt``, whose roots are
    inside the unit circle iff ``K_v dt < 2`` and ``K_p dt² + 2 K_v dt < 4`` (``K_p > 0``); the
    gains are refused when ``K_p dt² + 2 K_v dt ≥ 4`` (the error would grow at every tick)."""
    kp = check_number(f"{name}: Kp", kp, 0.0, MAX_PD_GAIN, " 1/s²")
    kv = check_number(f"{name}: Kv", kv, 0.0, MAX_PD_GAIN, " 1/s")
    check_stable_gains(name, kp, kv, dt)
    return kp, kv


def check_stable_gains(name: str, kp: float, kv: float, dt: float) -> None:
    """:class:`InvalidInput` when ``K_p dt² + 2 K_v dt ≥ 4`` (see :func:`check_pd_gains`)."""
    if kp * dt**2 + 2 * kv * dt >= 4.0:
        raise InvalidInput(f"{name}: Kp = {kp:g} 1/s², Kv = {kv:g} 1/s make the loop unstable at dt = {dt:g} s: "
                           f"Kp dt² + 2 Kv dt must be < 4, got {kp * dt**2 + 2 * kv * dt:g}")


def unconnected_input(error: BaseException, system: str) -> str | None:
    """The name of the input port of the system named ``system`` that ``error`` (Drake's "required
    InputPort[i] (port) of System ::…::system (…) is not connected", :func:`~sotdrake.task.unconnected_port`)
    says is not connected; None for another error, or another system's port."""
    found = unconnected_port(error)
    return found[0] if found is not None and found[1] == system else None


def usable_task_rows(J: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> bool:
    """Whether a task's rows ``lower ≤ J q̈ ≤ upper`` can be solved: ``J`` finite, no NaN bound, and
    an infinite bound only as the open side of an inequality (``lower = −∞`` or ``upper = +∞``): an
    equality row (or a bound) at ±∞ asks an infinite acceleration."""
    return bool(np.isfinite(J).all() and not np.isnan(lower).any() and not np.isnan(upper).any()
                and not np.isposinf(lower).any() and not np.isneginf(upper).any())
