"""The physical ranges every command accepts (a value outside is refused with an ``InvalidInput``
naming the argument and the range, and nothing changes).

The ranges are generous for a humanoid or a manipulator, and narrow enough that no accepted value
overflows in the maths (exponentials, ``lie.py``'s trigonometry, the device's integration):

============================  ==================  =============================================
what                          range               why
============================  ==================  =============================================
target position (m)           ``|x| ≤ 100``       a workspace of 100 m around the world origin
target angle (rad)            ``|θ| ≤ 2π``        roll, pitch, yaw of a 6-vector target
target velocity (m/s, rad/s)  ``|v| ≤ 100``       feed-forward velocities
joint-space target            ``|q| ≤ 100``       postures (rad or m)
gain λ (1/s)                  ``0 ≤ λ ≤ 1e4``     and, with the control period ``dt`` known,
                                                  ``λ·dt < 2`` (the discrete loop
                                                  ``e ← (1 - λ dt) e`` diverges from 2; a
                                                  warning from ``λ·dt ≥ 1``, where it overshoots)
gain decay rate b (1/unit)    ``0 ≤ b ≤ 1e6``     ``exp(-b‖e‖)`` of the adaptive gain
error scale (unit of e)       ``1e-6 ≤ e ≤ 1e3``  ``e_ref`` of ``setByPoint``, ``d`` of the
                                                  hyperbolic gain (``|d| ≤ 1e3``)
============================  ==================  =============================================
"""

from __future__ import annotations

import math

MAX_TARGET_POSITION = 100.0  # m
MAX_TARGET_ANGLE = 2 * math.pi  # rad
MAX_TARGET_VELOCITY = 100.0  # m/s or rad/s
MAX_JOINT_TARGET = 100.0  # rad or m
MAX_GAIN = 1e4  # 1/s
MAX_GAIN_DECAY = 1e6  # 1/unit of the error
ERROR_SCALE = (1e-6, 1e3)  # unit of the error
#: λ·dt at and above which a gain is refused (the discrete loop diverges), and warned about.
GAIN_DT_REFUSED = 2.0
GAIN_DT_WARNED = 1.0
