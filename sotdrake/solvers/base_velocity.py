"""The floating base's velocity bound, from the legs' joint velocity limits.

A humanoid's base moves through its legs: with a foot on the ground, the base turns at a rate the
leg joints produce and moves at that rate times the leg's length. The default bound is therefore

* angular, each component of ``ω_WB`` (rad/s): ``ω̄ = min`` of the leg joints' velocity limits
  (3.87 rad/s for TALOS, its hip yaw);
* linear, each component of ``v_WB`` (m/s): ``v̄ = ω̄ · L``, with ``L`` the distance from the base
  to the sole in the reference posture (1.02 m for TALOS in half-sitting: 3.95 m/s).

Robots without ``leg`` joints or soles use all their joints' limits and ``L = 1 m``. The solvers take
it as a hard bound (``SolverKine``) or in the uniform scaling (``SOT``); ``setBaseVelocityLimit``
changes it.
"""

from __future__ import annotations

import numpy as np

from ..configuration import Layout
from ..exceptions import SotError

#: Largest accepted base velocity bound (rad/s, m/s).
MAX_BASE_VELOCITY = 100.0


def default_base_velocity_limit(model) -> tuple[float, float]:
    """``(ω̄, v̄)``: see the module docstring."""
    plant = model.plant
    legs, joints = [], []
    for index in plant.GetJointIndices():
        joint = plant.get_joint(index)
        if joint.num_velocities() == 1:
            limit = float(min(-joint.velocity_lower_limits()[0], joint.velocity_upper_limits()[0]))
            joints.append(limit)
            if "leg" in joint.name():
                legs.append(limit)
    candidates = [x for x in (legs or joints) if np.isfinite(x) and x > 0]
    angular = min(candidates) if candidates else 1.0
    length = 1.0
    try:
        context = plant.CreateDefaultContext()
        plant.SetPositions(context, model.half_sitting)
        base = plant.get_body(next(iter(plant.GetFloatingBaseBodies()))).body_frame()
        length = float(np.linalg.norm(plant.CalcRelativeTransform(context, base, model.frame("left-sole")).translation()))
    except (StopIteration, SotError):  # no floating base or no sole: the documented 1 m
        length = 1.0
    return angular, angular * length


def velocity_limit_vector(model, base: tuple[float, float] | None = None) -> np.ndarray:
    """nv positive limits for :func:`~.velocity_scaling.scale_to_limits`: each joint's
    ``min(-v_min, v_max)``, and ``base`` (default :func:`default_base_velocity_limit`) on the
    floating base's angular then linear components."""
    plant = model.plant
    limit = np.minimum(-plant.GetVelocityLowerLimits(), plant.GetVelocityUpperLimits())
    layout = Layout.of(plant)
    if layout.base_v is not None:
        angular, linear = base if base is not None else default_base_velocity_limit(model)
        iv = layout.base_v
        limit[iv : iv + 3], limit[iv + 3 : iv + 6] = angular, linear
    return limit
